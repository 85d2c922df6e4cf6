"""`impactlab contact`: the designer for any MuJoCo user, and its output run in plain MuJoCo.

The snippet and the tuned model are checked the way a user would: pasted into an MJCF model
and simulated with MuJoCo's own `rollout` (no impactlab recorder), e measured from the
states just outside each contact, at every bounce of a drop.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from mujoco import rollout

from impactlab.cli import main

ALONE = ["contact", "--restitution", "0.8", "--radius", "0.05", "--speed", "0.5..4"]
BALL = """<mujoco model="user">
  <!-- a user's model: comments, odd   spacing and attribute order stay as they are -->
  <option timestep="{dt}" integrator="{integrator}"/>
  <worldbody>
    <light pos="0 0 3"/>
    <geom name="floor" type="plane" size="2 2 0.1" friction="0.8 0.01 0.001"/>
    <body name="ball" pos="0 0 {z}">
      <freejoint/>
      <geom name="ballgeom" type="sphere" size="{r}" mass="0.2"/>
    </body>
    <body name="box" pos="1 0 0.5"><freejoint/><geom name="boxgeom" type="box" size=".1 .1 .1"/></body>
  </worldbody>
</mujoco>
"""


def run_cli(capsys, *args: str) -> tuple[int, str, str]:
    try:
        code = main(list(args))
    except SystemExit as exc:  # a wrong option: argparse's one line and exit code 2
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def bounces(model: mujoco.MjModel, radius: float, seconds: float) -> list[tuple[float, float]]:
    """(impact speed, e) of every complete bounce of the model's first free body on z = 0,
    as the recorder takes them: the speed before any contact force acted (in the first state
    in contact; RK4: the state before, whose step's later stages met the floor) and in the
    first state out of contact."""
    data = mujoco.MjData(model)
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, kind))
    mujoco.mj_getState(model, data, state0, kind)
    state, _ = rollout.rollout(model, data, state0[None], nstep=int(seconds / model.opt.timestep))
    z, vz = state[0, :, 3], state[0, :, 1 + model.nq + 2]
    inside = z < radius
    before = int(model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4)
    out = []
    for start in np.flatnonzero(~inside[:-1] & inside[1:]) + 1:
        end = start + int(np.argmax(~inside[start:]))
        if end > start:
            v_in = vz[start - before]
            out.append((-v_in, -vz[end] / v_in))
    return out


def test_alone_prints_parameters_prediction_and_pair(capsys):
    code, out, err = run_cli(capsys, *ALONE, "--timestep", "1e-5")
    assert code == 0 and not err
    for words in ("solref", "solimp", "worst |e - 0.8|", "worst penetration", "steps", "<pair"):
        assert words in out
    assert "below the range" in out
    code, out, _ = run_cli(capsys, *ALONE, "--timestep", "1e-5", "--json")
    doc = json.loads(out)
    assert code == 0 and doc["ok"] and doc["speed_range_mps"] == [0.5, 4.0]
    assert doc["predicted"]["worst_error_in_range"] <= 0.005
    assert doc["max_penetration_m"] <= 0.02 * 0.05
    assert doc["solref"][0] == -doc["stiffness"] and doc["integrator"] == "Euler"


@pytest.mark.slow
@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_snippet_in_plain_mujoco_holds_e_at_every_bounce(capsys, integrator):
    """The printed <pair>, pasted into a model, simulated by MuJoCo alone (the implicitfast
    model of `test_model_is_written_back...` runs the same way)."""
    r, dt = 0.05, 1e-5
    code, out, _ = run_cli(
        capsys, *ALONE, "--timestep", str(dt), "--integrator", integrator, "--json"
    )
    doc = json.loads(out)
    assert code == 0 and doc["integrator"] == integrator
    pair = doc["mjcf_pair"].replace("GEOM1", "floor").replace("GEOM2", "ballgeom")
    z = r + 3.0**2 / (2 * 9.81)  # first impact at 3 m/s
    xml = BALL.format(dt=dt, integrator=integrator, z=z, r=r)
    xml = xml.replace("</mujoco>", f"<contact>{pair}</contact></mujoco>")
    hits = bounces(mujoco.MjModel.from_xml_string(xml), r, 1.3)
    in_range = [(v, e) for v, e in hits if 0.5 <= v <= 4.0]
    assert len(in_range) >= 3, hits
    assert max(abs(e - 0.8) for _, e in in_range) <= 0.005, in_range


@pytest.mark.slow
def test_too_coarse_prints_the_best_and_the_timestep_needed(capsys):
    code, out, err = run_cli(capsys, *ALONE, "--timestep", "5e-4")
    assert code == 1 and not err
    assert "NOT MET" in out and "timestep <= " in out and "best at 0.0005 s" in out
    code, out, _ = run_cli(capsys, *ALONE, "--timestep", "5e-4", "--json")
    doc = json.loads(out)
    assert code == 1 and not doc["ok"] and doc["best"]["predicted"]["worst_error_in_range"] > 0
    needed = doc["timestep_max_s"]
    code, out, _ = run_cli(capsys, *ALONE, "--timestep", repr(0.98 * needed), "--json")
    assert code == 0 and json.loads(out)["ok"]
    # a timestep a softer contact can meet: the penetration it needs, and it works
    code, out, _ = run_cli(capsys, *ALONE, "--timestep", "2.5e-5", "--json")
    softer = json.loads(out)["softer"]
    assert code == 1 and softer is not None
    pen = repr(softer["max_penetration_m_to_ask"])
    code, out, _ = run_cli(capsys, *ALONE, "--timestep", "2.5e-5", "--max-penetration", pen)
    assert code == 0, out


def write_ball(tmp_path: Path, *, dt: float = 1e-5, integrator: str = "implicitfast") -> Path:
    path = tmp_path / "ball.xml"
    path.write_text(BALL.format(dt=dt, integrator=integrator, z=0.6, r=0.05))
    return path


@pytest.mark.slow
def test_model_is_written_back_with_a_calibrated_pair_and_nothing_else(tmp_path, capsys):
    model = write_ball(tmp_path)
    out_path = tmp_path / "tuned.xml"
    code, out, err = run_cli(
        capsys, "contact", str(model), "--pair", "ballgeom/floor=0.8", "-o", str(out_path)
    )
    assert code == 0 and not err and "wrote" in out
    original, tuned = model.read_text(), out_path.read_text()
    start = tuned.index("  <contact>")
    end = tuned.index("</contact>\n") + len("</contact>\n")
    assert tuned[:start] + tuned[end:] == original  # every other byte as it was
    # the model's own friction is kept, the speeds come from the model (drop from 0.6 m)
    assert 'friction="1 1 0.01 0.001 0.001"' in tuned and 'condim="3"' in tuned
    v1 = math.sqrt(2 * 9.81 * 0.55)
    assert f"0.5..{v1:.4g} m/s" in out
    hits = bounces(mujoco.MjModel.from_xml_path(str(out_path)), 0.05, 1.5)
    in_range = [e for v, e in hits if v >= 0.5]
    assert len(in_range) >= 3 and max(abs(e - 0.8) for e in in_range) <= 0.005, hits
    # tuning the tuned model replaces its pair: the same file again
    again = tmp_path / "again.xml"
    code, _, _ = run_cli(
        capsys, "contact", str(out_path), "--pair", "floor/ballgeom=0.8", "-o", str(again)
    )
    assert code == 0 and again.read_text() == tuned


def test_an_existing_named_pair_is_replaced_and_the_others_kept(tmp_path, capsys):
    text = BALL.format(dt=1e-5, integrator="Euler", z=0.6, r=0.05).replace(
        "</mujoco>",
        '  <contact>\n    <pair name="hit" geom1="floor" geom2="ballgeom" solref="0.02 1"/>\n'
        '    <pair geom1="floor" geom2="boxgeom"/>\n  </contact>\n</mujoco>',
    )
    model = tmp_path / "m.xml"
    model.write_text(text)
    code, out, _ = run_cli(
        capsys,
        "contact",
        str(model),
        "--pair",
        "ballgeom/floor=0.5@1..3",
        "-o",
        str(tmp_path / "t.xml"),
        "--json",
    )
    doc = json.loads(out)
    assert code == 0 and doc["pairs"][0]["speed_range_mps"] == [1.0, 3.0]
    tuned = (tmp_path / "t.xml").read_text()
    assert tuned.count("<pair ") == 2 and '<pair name="hit" geom1="floor" geom2="ballgeom"' in tuned
    assert '<pair geom1="floor" geom2="boxgeom"/>' in tuned and 'solref="0.02 1"' not in tuned


def test_a_coarse_model_gets_advice_and_no_file(tmp_path, capsys):
    model = write_ball(tmp_path, dt=2e-4)
    out_path = tmp_path / "tuned.xml"
    code, out, _ = run_cli(
        capsys, "contact", str(model), "--pair", "ballgeom/floor=0.8", "-o", str(out_path)
    )
    assert code == 1 and "timestep <= " in out and "nothing written" in out
    assert not out_path.exists() and list(tmp_path.iterdir()) == [model]


def test_a_tuned_model_that_does_not_load_from_its_folder_is_not_left_behind(tmp_path, capsys):
    (tmp_path / "parts.xml").write_text("<mujoco><worldbody/></mujoco>")
    model = write_ball(tmp_path)
    model.write_text(
        model.read_text().replace("<worldbody>", '<include file="parts.xml"/>\n  <worldbody>')
    )
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    code, _, err = run_cli(
        capsys,
        "contact",
        str(model),
        "--pair",
        "ballgeom/floor=0.8",
        "-o",
        str(elsewhere / "t.xml"),
    )
    assert code == 2 and "parts.xml" in err and len(err.strip().splitlines()) == 1
    assert list(elsewhere.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--restitution", "0.8", "--radius", "0.05", "--timestep", "1e-5"], "--speed"),
        (["--radius", "0.05", "--speed", "1..3", "--timestep", "1e-5"], "--restitution"),
        ([*ALONE[1:], "--timestep", "fast"], "--timestep: must be a number"),
        ([*ALONE[1:5], "--speed", "3..1", "--timestep", "1e-5"], "LO <= HI"),
        ([*ALONE[1:5], "--speed", "0..1", "--timestep", "1e-5"], "0 < LO"),
        ([*ALONE[1:], "--timestep=-1e-5"], "timestep_s must be a positive"),
        ([*ALONE[1:], "--timestep", "1e-5", "--radius", "nan"], "finite"),
        (["--restitution", "0.05", "--radius", "0.1", "--speed", "1", "--timestep", "1e-5"], "0.1353"),
        ([*ALONE[1:], "--timestep", "1e-5", "--pair", "a/b=0.5"], "needs an MJCF model"),
        ([*ALONE[1:], "--timestep", "1e-5", "--max-penetration", "1e-3", "--duration", "1e-3"], "not both"),
        # absurd sizes: one error, not overflowing arithmetic or an endless emulation
        ([*ALONE[1:5], "--speed", "1e-300..1", "--timestep", "1e-5"], "outside what the designer"),
        ([*ALONE[1:], "--timestep", "1e-30"], "outside what the designer handles (1e-09 .. 1)"),
        ([*ALONE[1:], "--timestep", "1e-5", "--radius", "1e30"], "radius_m = 1e+30 m is outside"),
        ([*ALONE[1:], "--timestep", "1e-5", "--gravity", "1e9"], "gravity_mps2 = 1e+09"),
    ],
)  # fmt: skip
def test_bad_input_is_one_line_and_exit_2(capsys, args, words):
    code, out, err = run_cli(capsys, "contact", *args)
    assert code == 2 and not out
    assert len(err.strip().splitlines()) == 1 and words in err, err


@pytest.mark.parametrize(
    ("pair", "extra", "words"),
    [
        ("ballgeom/flor=0.8", [], "no geom named 'flor'"),
        ("ballgeom=0.8", [], "GEOM1/GEOM2=E"),
        ("ballgeom/floor", [], "give its restitution"),
        ("ballgeom/floor=high", [], "must be a number"),
        ("boxgeom/floor=0.5", ["--speed", "1..2"], "--max-penetration or --duration"),
        ("ballgeom/boxgeom=0.5", [], "--speed LO..HI"),
        ("ballgeom/floor=0.8", ["--timestep", "1e-5"], "--timestep comes from the model"),
        ("ballgeom/floor=0.8", ["--radius", "0.1"], "--radius comes from the model"),
        ("ballgeom/floor=0.8", ["-o", "."], "is a folder"),
    ],
)
def test_bad_model_input_is_one_line_and_exit_2(tmp_path, capsys, pair, extra, words):
    model = write_ball(tmp_path)
    code, out, err = run_cli(capsys, "contact", str(model), "--pair", pair, *extra)
    assert code == 2 and not out
    assert len(err.strip().splitlines()) == 1 and words in err, err


def test_missing_and_broken_models(tmp_path, capsys):
    code, _, err = run_cli(capsys, "contact", str(tmp_path / "no.xml"), "--pair", "a/b=0.5")
    assert code == 2 and "file not found" in err
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><geom type='sphere'/></worldbody>")
    code, _, err = run_cli(capsys, "contact", str(bad), "--pair", "a/b=0.5")
    assert code == 2 and "invalid MJCF" in err and len(err.strip().splitlines()) == 1


def test_box_on_the_floor_with_a_penetration_bound(tmp_path, capsys):
    model = write_ball(tmp_path)
    code, out, _ = run_cli(
        capsys, "contact", str(model), "--pair", "boxgeom/floor=0.5@1..2",
        "--max-penetration", "0.002", "--json",
    )  # fmt: skip
    doc = json.loads(out)
    assert code == 0 and doc["pairs"][0]["radius_m"] is None
    assert "one contact point" in doc["pairs"][0]["notes"][0]


def test_help_lists_the_command(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "contact" in capsys.readouterr().out
    from impactlab.cli.contact import INTEGRATORS
    from impactlab.contact import INTEGRATORS as CALIBRATED

    assert INTEGRATORS == CALIBRATED


CURVE = ["--restitution", "1:0.85,4:0.78", "--radius", "0.033", "--timestep", "1e-5"]


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--restitution", "1:0.85,0.5:0.86", "--radius", "0.033", "--timestep", "1e-5"], "strictly ascending"),
        (["--restitution", "1:0.85,2:1.2", "--radius", "0.033", "--timestep", "1e-5"], "e[1] must be"),
        (["--restitution", "1:0.85,2", "--radius", "0.033", "--timestep", "1e-5"], "SPEED:E"),
        (["--restitution", "1:0.85,2:x", "--radius", "0.033", "--timestep", "1e-5"], "must be a number"),
        (["--restitution", "1:0.85", "--radius", "0.033", "--timestep", "1e-5"], "2..64 speeds"),
        (["--restitution", "0:0.85,1:0.8", "--radius", "0.033", "--timestep", "1e-5"], "speed_mps[0]"),
        (["--restitution", ",".join(f"{i + 1}:0.8" for i in range(65)), "--timestep", "1e-5"], "2..64"),
        (["--law", "0.25", "--speed", "1..8", "--timestep", "1e-5"], "C1,C2"),
        (["--law", "0.25,0.04", "--timestep", "1e-5", "--radius", "0.033"], "--law needs --speed"),
        (["--law", "3,0", "--speed", "1..8", "--timestep", "1e-5", "--radius", "0.033"], "e[0] must be"),
        (["--law", "0.25,0.04", "--speed", "1", "--timestep", "1e-5", "--radius", "0.033"], "0 < lo < hi"),
        (["--law", "0.25,0.04", *CURVE], "not both"),
        ([*CURVE, "--speed", "0.5..4"], "outside the curve's points"),
        ([*CURVE, "--reference-speed", "9"], "outside the speeds"),
        ([*CURVE[:2], "--radius", "0.033"], "--timestep is required"),
        (["--restitution", "0.01:0.9,5:0.8", "--radius", "0.033", "--timestep", "1e-5"], "narrower"),
        ([*ALONE[1:], "--timestep", "1e-5", "--reference-speed", "2"], "for a target e(v)"),
        ([*CURVE[:4], "--timestep", "0.01"], "too coarse"),
        (["--restitution", "1000:0.85,4000:0.8", "--radius", "0.033", "--timestep", "1e-5"], "too coarse"),
    ],
)  # fmt: skip
def test_bad_curve_input_is_one_line_and_exit_2(capsys, args, words):
    """Every malformed table, law or request: one line, exit 2, before any fit."""
    code, out, err = run_cli(capsys, "contact", *args)
    assert code == 2 and not out
    assert len(err.strip().splitlines()) == 1 and words in err, err


def test_a_curve_needs_no_model(tmp_path, capsys):
    model = tmp_path / "ball.xml"
    model.write_text(BALL.format(dt="1e-5", integrator="Euler", z="0.5", r="0.05"))
    code, out, err = run_cli(capsys, "contact", str(model), "--restitution", "1:0.85,4:0.78")
    assert code == 2 and not out and "designed without a model" in err


@pytest.mark.slow
def test_curve_text_and_json(capsys):
    """A table: solref/solimp, e at each point and the worst speed between them, the
    penetration, the contact time and the resting sink; --json the same numbers; the pair
    snippet runs in plain MuJoCo with e at 2.5 m/s (between the points) on the curve."""
    code, out, _ = run_cli(capsys, "contact", *CURVE)
    assert code == 0, out
    for words in ("(point)", "(worst between)", "of the radius", "contact time", "sinks"):
        assert words in out
    code, out, _ = run_cli(capsys, "contact", *CURVE, "--json")
    doc = json.loads(out)
    assert code == 0 and doc["ok"] and doc["tolerance"] == 0.01
    assert doc["curve"] == {"speed_mps": [1.0, 4.0], "e": [0.85, 0.78]}
    assert doc["predicted"]["worst_error_in_range"] <= 0.01
    assert 0 < doc["rest_sink_fraction_of_radius"] < 0.1
    xml = BALL.format(dt="1e-5", integrator="Euler", z="0.5", r="0.033").replace(
        "</worldbody>",
        "</worldbody><contact>"
        + doc["mjcf_pair"].replace("GEOM1", "floor").replace("GEOM2", "ballgeom")
        + "</contact>",
    )
    model = mujoco.MjModel.from_xml_string(xml)
    model.geom_condim[:] = 1
    data = mujoco.MjData(model)
    data.qpos[2] = 0.033 + 1e-4
    data.qvel[2] = -2.5
    z_prev = vz_prev = None
    for _ in range(20000):
        mujoco.mj_step(model, data)
        if data.qpos[2] < 0.033 and vz_prev is None:
            vz_prev = data.qvel[2]
        if vz_prev is not None and data.qpos[2] >= 0.033:
            z_prev = data.qvel[2]
            break
    assert z_prev is not None and vz_prev is not None
    target = 0.85 + (0.78 - 0.85) * (-vz_prev - 1.0) / 3.0
    assert abs(-z_prev / vz_prev - target) <= 0.01


@pytest.mark.slow
def test_curve_beyond_reach_exits_1(capsys):
    code, out, _ = run_cli(
        capsys, "contact", "--restitution", "1:0.9,3:0.75,10:0.6", "--radius", "0.033",
        "--timestep", "1e-5",
    )  # fmt: skip
    assert code == 1 and "NOT MET" in out and "nearest reachable curve" in out
