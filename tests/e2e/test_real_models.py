"""Real MJCF models nobody on this team wrote, recorded and analyzed as a user would.

The models ship in packages on the registries: dm_control's suite (a quadruped, a humanoid
whose head is a body welded to its torso, a dog of 176 meshes, an arm with a ball and a
peg, all with `<include>`s and rotor inertia (armature) in their joints) and MuJoCo's own
test model (springs, tendons, actuators, the energy flag). Every number is compared with
MuJoCo's own: the whole system's energy from the logged bodies and joints equals the log's
`/energy` (MuJoCo's sensors) at every logged step.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.cli import main
from impactlab.logs.load import RunLog, load_log

pytestmark = [pytest.mark.slow, pytest.mark.extras]  # real robot models (the models extra)

ENERGY_RTOL = 1e-6  # of the largest |MuJoCo total| of the run, at every logged step


def package_dir(name: str) -> Path:
    """Where an installed package lies (dm_control: the models extra; these tests are marked
    `extras`, so they are collected, and deselected, without it)."""
    spec = importlib.util.find_spec(name)
    return Path(spec.origin).parent if spec is not None and spec.origin else Path(f"<no {name}>")


SUITE = package_dir("dm_control") / "suite"
MODELS = {
    "quadruped": SUITE / "quadruped.xml",
    "humanoid": SUITE / "humanoid.xml",
    "dog": SUITE / "dog.xml",
    "manipulator": SUITE / "manipulator.xml",
    "mujoco_testdata": package_dir("mujoco") / "testdata" / "model.xml",
}


def record(model: Path, out: Path, *options: str) -> RunLog:
    code = main(["record", str(model), "-o", str(out), *options])
    assert code == 0
    (path,) = sorted(out.glob("*.mcap"))
    return load_log(path)


@pytest.fixture(scope="module")
def humanoid(tmp_path_factory) -> tuple[RunLog, RunLog]:
    """The humanoid collapsing for 2.5 s, logged every step and every 5th step."""
    root = tmp_path_factory.mktemp("humanoid")
    every1 = record(MODELS["humanoid"], root / "every1", "--duration", "2.5")
    every5 = record(
        MODELS["humanoid"], root / "every5", "--duration", "2.5", "--set", "logging.every=5"
    )
    return every1, every5


@pytest.mark.parametrize("name", list(MODELS))
def test_whole_system_energy_equals_mujocos_at_every_logged_step(tmp_path, name):
    run = record(MODELS[name], tmp_path, "--duration", "0.4")
    assert run.outcome == "completed", run.meta["reason"]
    result = analyze_run(run)
    total = result.energy.filter(pl.col("body") == "total")
    assert total.height == run.energy.height  # every logged step
    theirs = total["mujoco_total_J"].to_numpy()
    assert np.isfinite(theirs).all()
    diff = np.abs(total["mujoco_diff_J"].to_numpy())
    assert diff.max() <= ENERGY_RTOL * max(np.abs(theirs).max(), 1.0), diff.max()
    # every body that moves is logged, with its own energy rows
    moving = {b for b in run.body_info}
    assert moving == set(run.bodies)
    assert set(result.energy["body"].unique()) == moving | {"total"}


def test_jointed_links_and_rotor_energy_are_part_of_the_total(tmp_path):
    """The quadruped: 18 bodies logged (not only its free torso); its joints' armature holds
    kinetic energy that the bodies do not, and the total counts it."""
    run = record(MODELS["quadruped"], tmp_path, "--duration", "0.4")
    assert len(run.bodies) > 10
    assert run.body_info["torso"].motion == "articulated"  # a free root, but jointed legs
    assert run.body_info["ball"].motion == "free"  # the ball of the fetch task: ballistic
    rotor = run.joint_energy["kinetic"].to_numpy()
    assert rotor.max() > 0
    assert run.outcome == "completed"  # not cut short as "unstable with no source"


def test_welded_head_impact_is_found(humanoid):
    """The head has no joint: welded to the torso, it is part of the torso's rigid body
    (MuJoCo's tree, `body_weldid`), and its geom's impact on the floor is the torso's."""
    run, _ = humanoid
    assert "head" not in run.bodies and "head" in run.body_info["torso"].geoms
    first_touch = run.contacts.filter(pl.col("geom2") == "head")["t_s"].min()
    hits = analyze_run(run).bounces.filter(
        (pl.col("body") == "torso") & pl.col("impact_t_s").is_not_null()
    )
    assert hits.height >= 1
    first = hits.row(0, named=True)
    assert first["impact_t_s"] == pytest.approx(first_touch, abs=1e-9)  # the head's contact
    assert first["surface"] == "floor" and first["v_in_mps"] < -1.0
    assert first["max_penetration_m"] > 1e-3
    # not ballistic: no apex heights, and the note says why
    assert first["apex_before_m"] is None and first["e_apex"] is None


def test_impacts_agree_when_logged_every_step_and_every_fifth(humanoid):
    """The same impacts (time within 5 ms, speed within 5 %) at both logging strides."""
    a, b = (analyze_run(r).bounces.filter(pl.col("v_in_mps").is_not_null()) for r in humanoid)
    keys = ["body", "surface", "bounce"]
    joined = a.join(b, on=keys, suffix="_5")
    assert joined.height == a.height == b.height >= 3
    for row in joined.iter_rows(named=True):
        assert abs(row["impact_t_s"] - row["impact_t_s_5"]) <= 0.005, row
        assert abs(row["v_in_mps_5"] / row["v_in_mps"] - 1) <= 0.05, row


def test_no_restitution_outside_0_1_without_a_note(humanoid, tmp_path):
    runs = [*humanoid, record(MODELS["mujoco_testdata"], tmp_path, "--duration", "1")]
    for run in runs:
        bounces = analyze_run(run).bounces
        odd = bounces.filter((pl.col("e_velocity") > 1) | (pl.col("e_velocity") < 0))
        for e, note in odd.select("e_velocity", "note").iter_rows():
            assert note.startswith(f"e_velocity {e:.3g} is outside [0, 1]"), note


GRAVITY_OFF = """<mujoco>
  <option timestep="0.001"><flag gravity="disable"/></option>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="block" pos="0 0 0.5"><freejoint/><geom type="box" size="0.05 0.05 0.05"/></body>
  </worldbody>
</mujoco>
"""


def test_a_model_without_gravity_has_no_potential_energy(tmp_path):
    (tmp_path / "m.xml").write_text(GRAVITY_OFF)
    run = record(tmp_path / "m.xml", tmp_path / "logs", "--duration", "0.2")
    assert run.gravity.tolist() == [0.0, 0.0, 0.0]
    energy = analyze_run(run).energy
    assert energy["pe_J"].abs().max() == 0.0
    assert run.energy["potential"].abs().max() == 0.0  # MuJoCo's agrees


ARM = """<mujoco>
  <option timestep="0.0005"/>
  <worldbody>
    <geom name="table" type="box" pos="0.5 0 0.2" size="0.3 0.3 0.2"/>
    <body name="link" pos="0 0 0.6">
      <joint name="shoulder" type="hinge" axis="0 1 0"/>
      <geom name="arm" type="capsule" fromto="0 0 0 0.6 0 0" size="0.03"/>
    </body>
  </worldbody>
  <keyframe><key name="home" qpos="-0.3"/></keyframe>
</mujoco>
"""


def test_a_model_without_a_free_body_has_impacts(tmp_path):
    """An arm on a hinge swings down onto a table: no free body, still an impact."""
    (tmp_path / "arm.xml").write_text(ARM)
    run = record(tmp_path / "arm.xml", tmp_path / "logs", "--duration", "0.6")
    assert run.body_info["link"].motion == "articulated"
    hits = analyze_run(run).bounces.filter(pl.col("v_in_mps").is_not_null())
    assert hits.height >= 1 and hits["surface"][0] == "table"
    assert hits["v_in_mps"][0] < -0.5


def test_a_run_starts_from_a_named_keyframe(tmp_path, capsys):
    (tmp_path / "arm.xml").write_text(ARM)
    run = record(
        tmp_path / "arm.xml", tmp_path / "logs", "--duration", "0.01", "--set", "keyframe=home"
    )
    # the hinge at -0.3 rad about y lifts the capsule's far end: its centre is above 0.6 m
    assert run.bodies["link"]["z"][0] == pytest.approx(0.6 + 0.3 * np.sin(0.3), abs=1e-9)
    capsys.readouterr()
    code = main(
        [
            "record",
            str(tmp_path / "arm.xml"),
            "-o",
            str(tmp_path / "x"),
            "--duration",
            "0.01",
            "--set",
            "keyframe=nope",
        ]
    )
    err = capsys.readouterr().err
    assert code == 2 and "no keyframe named 'nope'" in err and "'home'" in err
    assert "Traceback" not in err and not (tmp_path / "x").exists()


RAMP = """<mujoco>
  <option timestep="0.001"/>
  <worldbody>
    <geom name="ramp" type="box" size="1 0.5 0.05" pos="0 0 0.5" euler="0 30 0"/>
    <body name="block" pos="0.6 0 0.6">
      <freejoint/><geom type="box" size="0.05 0.05 0.05" mass="0.5"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_a_body_above_a_ramp_starts_with_the_potential_energy_of_its_clearance(tmp_path):
    """The ramp's highest point (1.05 m) is above the block (0.6 m): the reference is the
    surface under the block, so it starts with m g (its clearance), not a negative energy."""
    (tmp_path / "ramp.xml").write_text(RAMP)
    run = record(tmp_path / "ramp.xml", tmp_path / "logs", "--duration", "0.05")
    (surface,) = run.surfaces
    assert surface.level_m > 1.0 > run.bodies["block"]["z"][0]
    energy = analyze_run(run).energy
    first = energy.filter(pl.col("body") == "block").row(0, named=True)
    clearance = run.clearance.filter(pl.col("surface") == "ramp")["clearance_m"][0]
    assert clearance > 0.2
    assert first["pe_J"] == pytest.approx(0.5 * 9.81 * clearance, rel=1e-9)
    assert first["height_m"] == pytest.approx(clearance, rel=1e-12)
    total = energy.filter(pl.col("body") == "total")
    assert total["mujoco_diff_J"].abs().max() < 1e-9


def test_every_command_runs_on_every_model_alone_and_in_one_batch(tmp_path, capsys):
    logs = tmp_path / "logs"
    for model in MODELS.values():
        assert main(["record", str(model), "-o", str(logs), "--duration", "0.3"]) == 0
    paths = sorted(logs.glob("*.mcap"))
    assert len(paths) == len(MODELS)
    assert main(["info", *map(str, paths)]) == 0
    assert main(["analyze", str(logs), "-o", str(tmp_path / "all"), "--no-figures"]) == 0
    for path in paths[:2]:  # alone, as well
        assert main(["analyze", str(path), "-o", str(tmp_path / path.stem), "--no-figures"]) == 0
    replay = [
        "replay",
        str(paths[0]),
        "-o",
        str(tmp_path / "r.rrd"),
        "--analysis",
        str(tmp_path / "all"),
    ]
    assert main(replay) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert (tmp_path / "all" / "report.md").is_file() and (tmp_path / "r.rrd").is_file()
