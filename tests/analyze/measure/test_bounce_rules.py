"""Which contacts are bounces, for whom, and how exact: per body and pair, chatter at rest
merged, e independent of the logging rate, the stop step logged, resting and rolling bodies,
surfaces other than a plane, MJCF run options, notes that are true, older logs."""

from __future__ import annotations

import math
import shutil

import numpy as np
import polars as pl
import pytest
from known import DROP_SPEC, G
from paths import GOLDEN, ROOT
from specs import ball, drop, spec, toml

import impactlab
from impactlab.analyze.measure.analysis import analyze_run
from impactlab.analyze.report import questions
from impactlab.analyze.report.context import Tables, labelled
from impactlab.cli import main
from impactlab.errors import LogError
from impactlab.logs.load import load_log
from impactlab.logs.reader import read_attachments

PAIRS_DT = 0.000004  # the largest timestep the designer accepts for e = 0.42 over 0.5..3.1 m/s
PAIRS = toml(
    spec(
        "pairs",
        {"a": ball(0.55, radius=0.05), "b": ball(0.55, x=0.5, radius=0.05)},
        timestep=PAIRS_DT,
        contact={
            "condim": 1,
            "pairs": {"a/plane": {"restitution": 0.42}, "b/plane": {"restitution": 0.88}},
        },
    )
)
TARGETS = {"a": 0.42, "b": 0.88}


@pytest.fixture(scope="module")
def pairs(record_spec):
    (path,) = record_spec("pairs", PAIRS)
    return analyze_run(load_log(path))


@pytest.mark.slow
def test_each_ball_keeps_its_own_e(pairs):
    """Two balls side by side, per-pair targets 0.42 and 0.88: each ball's e is its own
    target (within 0.01 above 0.5 m/s, where the calibrated contact holds it) and never mixed."""
    b = pairs.bounces
    for body, target in TARGETS.items():
        mine = b.filter((pl.col("body") == body) & pl.col("complete"))
        fast = mine.filter(pl.col("v_in_mps") <= -0.5)
        assert fast.height >= 2
        np.testing.assert_allclose(fast["e_velocity"], target, atol=0.01)
        assert fast["e_velocity"].max() - fast["e_velocity"].min() < 0.01
        assert ((mine["e_velocity"] > 0) & (mine["e_velocity"] < 1)).all()
        assert (mine["surface"] == "plane").all()
    tables = Tables(pl.DataFrame([pairs.summary]), b, pl.DataFrame(), pl.DataFrame(), {}, {})
    (lead, *_) = questions.restitution(labelled(tables)).lead
    text = str(getattr(lead, "text", lead))
    assert text.startswith("Yes, e is constant across bounces"), text
    # a's slow bounces, below its calibrated speed range, are named apart with their e
    slow = b.filter((pl.col("body") == "a") & pl.col("complete") & pl.col("target_e").is_null())
    assert slow.height and (slow["v_in_mps"] > -0.5).all()
    assert "in the calibrated speed range (outside it: e " in text
    assert pairs.summary["e_velocity_mean"] is None  # never an average over both balls
    assert "2 body-surface pairs" in pairs.summary["note"]


@pytest.mark.slow
def test_chatter_at_rest_is_one_resting_contact(pairs):
    """Ball a comes to rest: its contact flickers on and off at micrometres per second; that is
    one resting contact (still open at the end), not dozens of bounces with e = -1."""
    a = pairs.bounces.filter(pl.col("body") == "a").sort("bounce")
    last = a.row(-1, named=True)
    assert not last["complete"] and last["e_velocity"] is None
    assert last["note"].startswith("still in contact with plane")
    # every contact of a with the plane before it is an impact: the flicker is merged
    episodes = pairs.intervals.filter(pl.col("body") == "a")
    assert episodes.filter(~pl.col("open"))["impact"].all()
    assert episodes.height == a.height
    # the bounces before rest are real flights: each rises as high as its release speed says
    flights = a.filter(pl.col("apex_m").is_not_null())  # to one step's speed change, g dt
    dv = 2 * G * PAIRS_DT / flights["v_out_mps"].to_numpy()
    assert (np.abs(flights["apex_m"] / flights["apex_predicted_m"] - 1) <= dv).all()


@pytest.mark.slow
def test_no_collision_note_for_balls_that_were_not_meant_to_collide(pairs):
    assert pairs.collisions.is_empty()
    assert "collision" not in pairs.summary["note"]


@pytest.mark.slow
@pytest.mark.parametrize("extra", [(), ("ball.angvel=[3.0, 40.0, 7.0]", "contact.condim=3")])
def test_e_does_not_depend_on_the_logging_rate(record_spec, extra):
    """The same toss logged every 1, 7 and 25 steps: the same e, impact speeds and apexes
    (the requirement is 1e-4; the ballistic extrapolation gives them to rounding), and the
    last apex, where the stop rule ended the run, is in every log."""
    runs = {
        n: analyze_run(
            load_log(record_spec("known_drop", DROP_SPEC, [f"logging.every={n}", *extra])[0])
        )
        for n in (1, 7, 25)
    }
    every_step = runs[1].bounces
    assert every_step["complete"].to_list() == [True, True, True]
    assert every_step["apex_m"].is_not_null().all()
    for n in (7, 25):
        b = runs[n].bounces
        assert runs[n].summary["log_every"] == n
        for col in ("e_velocity", "v_in_mps", "v_out_mps", "apex_m", "e_apex"):
            np.testing.assert_allclose(b[col], every_step[col], rtol=0, atol=1e-9, err_msg=col)


def test_the_stop_step_is_logged(record_spec):
    """Logged every 7 steps, the run still ends on the step the stop rule stopped on."""
    (path,) = record_spec("known_drop", DROP_SPEC, ["logging.every=7"])
    run = load_log(path)
    ball = run.bodies["ball"].sort("t_ns")
    steps = int(run.meta["steps"])
    assert ball["t_ns"][-1] == (steps - 1) * 100_000  # dt = 0.1 ms
    assert (steps - 1) % 7 != 0  # off the logging grid here
    assert ball["vz"][-1] <= 0 < ball["vz"][-2]  # the apex after the last bounce


@pytest.mark.parametrize(
    ("v", "w"), [(0.0, 0.0), (1.0, 10.0), (1.0, 0.0)], ids=["rest", "rolling", "sliding"]
)
def test_resting_rolling_and_sliding_balls_make_no_bounce(record_spec, v, w):
    (path,) = record_spec(
        "rest", drop("rest", z=0.1, vel=[v, 0.0, 0.0], angvel=[0.0, w, 0.0], timestep=0.0005)
    )
    a = analyze_run(load_log(path))
    assert a.summary["n_bounces"] == 0
    (row,) = a.bounces.rows(named=True)
    assert row["bounce"] is None and row["body"] == "ball"
    assert row["note"].startswith("at rest, sliding or rolling on plane")
    assert a.summary["energy_initial_J"] == pytest.approx(
        0.5 * (v * v) + 0.5 * 0.004 * w * w, abs=1e-12
    )
    assert a.summary["mujoco_diff_max_J"] < 1e-9


@pytest.mark.slow
def test_a_ball_at_rest_on_the_plane_is_analyzed_with_figures(tmp_path, capsys):
    """`free_fall.toml --set ball.pos=[0,0,0.1]`: analyze with figures and report, no traceback."""
    spec = ROOT / "experiments" / "free_fall.toml"
    logs, results = tmp_path / "logs", tmp_path / "results"
    assert (
        main(
            [
                "record",
                str(spec),
                "--set",
                "ball.pos=[0, 0, 0.1]",
                "--set",
                "stop.max_time=0.5",
                "-o",
                str(logs),
            ]
        )
        == 0
    )
    assert main(["analyze", str(logs), "-o", str(results)]) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert list((results / "figures").glob("energy-*.png"))
    assert not list((results / "figures").glob("bounce-decay-*.png"))  # no bounce, no decay
    assert "at rest, sliding or rolling on plane" in (results / "report-appendix.md").read_text()


TABLE = """<mujoco model="table">
  <option timestep="0.0001"/>
  <asset><mesh name="block" vertex="-1 -1 0  1 -1 0  -1 1 0  1 1 0  -1 -1 1  1 -1 1  -1 1 1  1 1 1" scale="0.3 0.3 0.3"/></asset>
  <default><geom condim="1" solref="-100000 -63.245553" solimp="0.9999 0.9999 0.001 0.5 2"/></default>
  <worldbody>
    <geom name="floor" type="plane" size="3 3 0.1"/>
    <body name="stand" pos="0 0 0"><geom name="table" type="box" size="0.3 0.3 0.2" pos="0 0 0.2"/></body>
    <geom name="block" type="mesh" mesh="block" pos="1 0 0"/>
    <body name="ball" pos="0 0 0.9"><freejoint/><geom name="ball" size="0.05" mass="1"/></body>
    <body name="cube" pos="1 0 0.85"><freejoint/><geom name="cube" type="box" size="0.05 0.05 0.05" mass="1"/></body>
  </worldbody>
</mujoco>
"""


def test_landing_on_a_table_and_on_a_mesh(record_model):
    """A ball onto a static box (a table on a static body) and a cube onto a static mesh:
    heights and energy from the surface each lands on, not from the floor."""
    run = load_log(record_model("table", TABLE, ["stop.max_time=0.6"]))
    levels = {s.name: s.level_m for s in run.surfaces}
    assert levels == pytest.approx({"floor": 0.0, "table": 0.4, "block": 0.3}, abs=1e-7)
    a = analyze_run(run)
    assert a.summary["energy_initial_J"] == pytest.approx(
        G * (0.9 - 0.45) + G * (0.85 - 0.35),
        rel=1e-7,  # the mesh's vertices are float32
    )
    assert a.summary["mujoco_diff_max_J"] < 1e-9
    first = a.bounces.filter(pl.col("bounce") == 1)
    by_body = {r["body"]: r for r in first.rows(named=True)}
    assert by_body["ball"]["surface"] == "table" and by_body["cube"]["surface"] == "block"
    assert by_body["ball"]["apex_before_m"] == pytest.approx(0.45, abs=1e-9)
    assert by_body["cube"]["apex_before_m"] == pytest.approx(0.5, abs=1e-6)  # mesh in float32
    for r in by_body.values():
        assert r["complete"] and r["e_velocity"] == pytest.approx(0.7441, abs=0.005)


HFIELD = """<mujoco model="field">
  <option timestep="0.0005"/>
  <asset><hfield name="hf" nrow="3" ncol="3" size="1 1 0.1 0.1" elevation="0 0 0 0 0 0 0 0 0"/></asset>
  <worldbody>
    <geom name="field" type="hfield" hfield="hf"/>
    <body name="ball" pos="0 0 0.5"><freejoint/><geom name="ball" size="0.05" mass="1"/></body>
  </worldbody>
</mujoco>
"""


def test_a_height_field_without_distances_says_so(record_model):
    """MuJoCo measures no distance to a height field: the bounce is found, heights are left
    empty with the reason."""
    run = load_log(record_model("field", HFIELD, ["stop.max_time=0.5"]))
    assert [(s.name, s.distance) for s in run.surfaces] == [("field", False)]
    a = analyze_run(run)
    first = a.bounces.row(0, named=True)
    assert first["surface"] == "field" and first["v_in_mps"] < -2.5
    assert first["apex_before_m"] is None
    assert a.summary["mujoco_diff_max_J"] < 1e-9


BOUNCY_BALL = """<mujoco model="ball">
  <option timestep="0.0001"/>
  <default><geom condim="1" solref="-100000 -63.245553" solimp="0.9999 0.9999 0.001 0.5 2"/></default>
  <worldbody>
    <geom type="plane" size="2 2 0.1"/>
    <body name="ball" pos="0 0 0.55"><freejoint/><geom size="0.05" mass="1"/></body>
    <body name="other" pos="1 0 0.55"><freejoint/><geom size="0.05" mass="1"/></body>
  </worldbody>
</mujoco>
"""


def test_mjcf_takes_the_run_options_of_a_spec(record_model):
    """--set logging.every / stop.bounces / stop.max_time on a user model, as on a spec."""
    path = record_model(
        "options", BOUNCY_BALL, ["stop.max_time=3", "stop.bounces=1", "logging.every=10"]
    )
    run = load_log(path)
    assert run.meta["log_every"] == "10" and run.meta["reason"] == "apex after bounce 1"
    assert run.spec["stop"]["bounces"] == 1 and run.spec["logging"]["every"] == 10
    a = analyze_run(run)
    b = a.bounces.filter(pl.col("bounce") == 1)
    assert b["complete"].all() and b["apex_m"].is_not_null().all()  # the stop step's apex
    assert a.collisions.is_empty()  # two bodies that never meet, and were not meant to


def test_a_collision_that_was_expected_and_did_not_happen_says_so(record_model):
    run = load_log(
        record_model("missed", BOUNCY_BALL, ["stop.max_time=0.2", "stop.separation=0.1"])
    )
    col = analyze_run(run).collisions
    assert col.height == 1 and "never happened" in col["note"][0]


def test_older_logs_are_refused_with_how_to_record_them_again(tmp_path):
    """A log of format 1 (written before the recorder found contacts at every step) is not
    analyzed: one line names its format and what to do; the model it carries records again
    and that log is analyzed."""
    old = tmp_path / "old.mcap"
    shutil.copyfile(GOLDEN / "format1" / "drop_restitution.mcap", old)
    run = load_log(old)
    with pytest.raises(LogError, match=r"a log of format 1: .* record the run again"):
        analyze_run(run)
    model = tmp_path / "model.xml"
    model.write_bytes(read_attachments(old)["model.xml"])
    options = [f"logging.every={run.meta['log_every']}", "stop.bounces=1"]
    (today,) = impactlab.record(model, out=tmp_path / "today", duration=1.0, overrides=options)
    now = analyze_run(load_log(today.path))
    assert now.bounces["apex_m"][0] is not None
    assert now.summary["mujoco_diff_max_J"] < 1e-9
    assert math.isclose(now.summary["drop_height_m"], 0.05, abs_tol=1e-12)
