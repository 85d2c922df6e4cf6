"""User models (MJCF), recorded and analyzed as a new user would: the handout's own ball.xml,
a box landing flat and one landing on an edge, a capsule. Heights come from the ground the
model has, e from the contact point, checked against hand calculations from the logged
states; MuJoCo's own energy agrees with the analysis' to 1e-9 J after the reference shift.

The bouncy models use MuJoCo's direct-form contact, solref = (-k, -b) with k = 1e5 1/s^2 and
b = 2 zeta sqrt(k), zeta = 0.1, solimp constant: a linear spring-dashpot in the contact's
normal coordinate, e = 0.7441 (Schwager-Poeschel) whatever the mass.
"""

from __future__ import annotations

import math

import numpy as np
import polars as pl
import pytest
from specs import DIRECT, drop, mjcf_drop, toml

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.analyze.measure.bounces import TURNING
from impactlab.cli import main
from impactlab.logs.load import RunLog, load_log

G = 9.81
E_DASHPOT = 0.7441  # Schwager-Poeschel, zeta = 0.1

# Step 1 of the handout, character for character
HANDOUT_BALL = """
<mujoco>
<option gravity="0 0 -9.81" timestep="0.0005"/>
<default>
<geom condim="1" solimp="0.9 0.95 0.001" solref="0.02 1"/>
</default>
<worldbody>
<light diffuse="1 1 1" pos="0 0 5"/>
<geom type="plane" size="5 5 0.1" rgba="0.8 0.8 0.8 1"/>
<body name="ball" pos="0 0 3">
<joint type="free"/>
<geom type="sphere" size="0.1" mass="1.0" rgba="1 0.2 0.2 1"/>
</body>
</worldbody>
</mujoco>
"""


@pytest.mark.slow
def test_handout_ball_as_written(tmp_path, capsys):
    """`impactlab record ball.xml --duration 2` then `impactlab analyze`: 28.45 J at the start,
    heights from the plane (the issue saw 0 J, -28.45 J, apexes of -2.886 m)."""
    model = tmp_path / "ball.xml"
    model.write_text(HANDOUT_BALL)
    assert main(["record", str(model), "--duration", "2", "-o", str(tmp_path / "logs")]) == 0
    assert main(["analyze", str(tmp_path / "logs"), "-o", str(tmp_path / "results")]) == 0
    capsys.readouterr()
    (path,) = (tmp_path / "logs").glob("*.mcap")
    a = analyze_run(load_log(path))
    s = a.summary
    assert s["energy_initial_J"] == pytest.approx(G * (3.0 - 0.1), rel=1e-12)  # 28.449 J
    assert s["mujoco_diff_max_J"] < 1e-9
    assert s["ground"] and s["drop_height_m"] == pytest.approx(2.9, abs=1e-12)
    height = a.energy.filter(pl.col("body") == "ball").sort("t_ns")["height_m"]
    assert height[0] == pytest.approx(2.9, abs=1e-12)
    # the lowest point above the plane dips by the deepest penetration, no more
    deepest = a.bounces["max_penetration_m"].max()
    assert height.min() == pytest.approx(-deepest, abs=1e-12)
    first = a.bounces.row(0, named=True)
    assert first["surface"] == "geom0"  # the handout's unnamed plane
    # the velocity it met the plane with: the free fall's, to one step's change g dt
    assert first["v_in_mps"] == pytest.approx(-math.sqrt(2 * G * 2.9), abs=G * 0.0005)
    assert first["apex_m"] > 0 and first["apex_m"] == pytest.approx(  # to one step's dv
        first["v_out_mps"] ** 2 / (2 * G), rel=2 * G * 0.0005 / first["v_out_mps"]
    )
    report = (tmp_path / "results" / "report.md").read_text()
    assert "| ball | 28.4 |" in report and "n/a" not in report  # Step 1: initial energy, J


@pytest.fixture(scope="module")
def flat_box(record_model) -> RunLog:
    path = record_model(
        "box",
        mjcf_drop("box", "box", "0.05 0.05 0.05", 0.55),
        ["stop.bounces=2", "stop.max_time=2"],
    )
    return load_log(path)


@pytest.fixture(scope="module")
def edge_box(record_model) -> RunLog:
    model = mjcf_drop("box", "box", "0.05 0.05 0.05", 0.6, euler="30 0 0")
    return load_log(record_model("box_edge", model, ["stop.max_time=0.6"]))


def hand_e(run: RunLog, bounce: int) -> tuple[float, float]:
    """e of the n-th contact with the floor from the logged rows around it, by hand.

    Contact point: the mean logged point at the first (last) row in contact, relative to the
    centre of mass then (its rotation over the one step to the row before or after is
    neglected). Its normal velocity u at the row before (after) the contact, v + w x r, is
    carried to the floor with the energy of a free flight: v^2 = u^2 + 2 g c, c the clearance
    at that row. Good to about (g + w^2 r) dt / v.
    """
    state = run.bodies["box"].sort("t_ns")
    t = state["t_ns"].to_numpy()
    touch = run.contacts.group_by("t_ns").agg(pl.col("x", "y", "z").mean()).sort("t_ns")
    steps = np.searchsorted(t, touch["t_ns"].to_numpy())
    starts = np.flatnonzero(np.diff(steps, prepend=-10) > 1)
    ends = np.append(starts[1:] - 1, len(steps) - 1)
    first, last = starts[bounce - 1], ends[bounce - 1]
    clearance = run.clearance.sort("t_ns")["clearance_m"].to_numpy()

    def normal_speed(row: int, contact: int) -> float:
        s = state.row(row, named=True)
        at = state.row(steps[contact], named=True)
        point = touch.row(contact, named=True)
        r = np.array([point[c] - at[c] for c in "xyz"])
        v = np.array([s[f"v{c}"] for c in "xyz"]) + np.cross([s[f"w{c}"] for c in "xyz"], r)
        return float(v[2])

    b, a = steps[first] - 1, steps[last] + 1
    v_in = -math.sqrt(normal_speed(b, first) ** 2 + 2 * G * clearance[b])
    v_out = math.sqrt(normal_speed(a, last) ** 2 + 2 * G * clearance[a])
    return v_in, v_out


def test_box_landing_flat(flat_box):
    a = analyze_run(flat_box)
    s = a.summary
    assert s["energy_initial_J"] == pytest.approx(G * (0.55 - 0.05), rel=1e-12)
    assert s["mujoco_diff_max_J"] < 1e-9
    assert flat_box.body_info["box"].rest_height_m == pytest.approx(0.05, abs=1e-12)
    b = a.bounces.sort("bounce")
    assert b["complete"].to_list() == [True, True]
    assert b["apex_before_m"][0] == pytest.approx(0.5, abs=1e-12)  # the face above the floor
    for row in b.iter_rows(named=True):
        v_in, v_out = hand_e(flat_box, row["bounce"])
        assert row["v_in_mps"] == pytest.approx(v_in, abs=G * 1e-4)
        assert row["v_out_mps"] == pytest.approx(v_out, abs=G * 1e-4)
        assert row["e_velocity"] == pytest.approx(E_DASHPOT, abs=0.005)
        # it does not turn: the apex measures e as well (to one step's speed change: v_out is
        # the velocity the faces parted with, the apex that of the continuous flight after)
        dv = G * flat_box.timestep_s
        assert row["e_apex"] == pytest.approx(row["e_velocity"], abs=dv / row["v_out_mps"])


def test_box_landing_on_an_edge(edge_box):
    """e at the edge that hits, not at the centre of mass; apexes of a turning box are empty."""
    a = analyze_run(edge_box)
    assert a.summary["mujoco_diff_max_J"] < 1e-9
    first = a.bounces.row(0, named=True)
    v_in, v_out = hand_e(edge_box, 1)
    assert first["v_in_mps"] == pytest.approx(v_in, abs=G * 1e-4)
    assert first["v_out_mps"] == pytest.approx(v_out, rel=2e-3)
    assert first["e_velocity"] == pytest.approx(-v_out / v_in, abs=2e-3)
    # the centre of mass leaves far slower than the edge: its e is not the contact's
    state = edge_box.bodies["box"].sort("t_ns")
    t = state["t_s"]
    before = state.filter(t < first["impact_t_s"])["vz"][-1]
    after = state.filter(t > first["release_t_s"])["vz"][0]
    assert abs(-after / before - first["e_velocity"]) > 0.1
    assert first["apex_m"] is None and first["e_apex"] is None and first["note"] == TURNING


def test_capsule(record_model):
    """A capsule lying flat (axis horizontal): heights of its lowest line, rest height = radius."""
    model = mjcf_drop("capsule", "capsule", "0.05 0.1", 0.55, euler="0 90 0")
    run = load_log(record_model("capsule", model, ["stop.bounces=2", "stop.max_time=2"]))
    assert run.body_info["capsule"].shape == "capsule"
    assert run.body_info["capsule"].rest_height_m == pytest.approx(0.05, abs=1e-12)
    a = analyze_run(run)
    assert a.summary["energy_initial_J"] == pytest.approx(G * 0.5, rel=1e-12)
    assert a.summary["mujoco_diff_max_J"] < 1e-9
    assert a.summary["drop_height_m"] == pytest.approx(0.5, abs=1e-12)
    b = a.bounces.filter(pl.col("complete"))
    assert b.height == 2
    np.testing.assert_allclose(b["e_velocity"], E_DASHPOT, atol=0.005)
    dv = G * run.timestep_s / b["v_out_mps"].to_numpy()  # one step's speed change
    assert (np.abs(b["e_apex"] - b["e_velocity"]) <= dv).all()


def centre_e(analysis) -> list[float]:
    """e from the centre of mass's vertical velocity at the first step in contact and the
    first after it (the recorder's states), per ground contact."""
    eps = analysis.intervals.filter(pl.col("kind") == "ground", ~pl.col("open"))
    return (-eps["s1_out_vz"] / eps["s1_in_vz"]).to_list()


SPINNING = toml(
    drop(
        "spinning",
        z=0.55,
        radius=0.05,
        vel=[0.5, 0.0, 0.0],
        angvel=[3.0, 40.0, 7.0],
        timestep=0.0001,
        contact={**DIRECT, "condim": 3},
        max_time=2.0,
        bounces=2,
    )
)


def test_contact_point_equals_centre_for_a_spinning_ball(record_spec, edge_box):
    """A spinning ball: its spin moves the contact point only along the floor, so e from the
    contact point is e from the centre (to rounding). For the box on its edge it is not."""
    (path,) = record_spec("spinning", SPINNING)
    run = load_log(path)
    assert run.bodies["ball"]["wy"][0] == 40.0
    a = analyze_run(run)
    spun = a.bounces
    assert spun["complete"].to_list() == [True, True]
    np.testing.assert_allclose(spun["e_velocity"], centre_e(a), rtol=1e-9)
    box = analyze_run(edge_box)
    assert abs(box.bounces["e_velocity"][0] - centre_e(box)[0]) > 0.05


def test_a_turning_box_gives_the_same_e_logged_every_25_steps(record_model, edge_box):
    """The cube landing on an edge spins after it: its contact point's impact and release
    are extrapolated with the rotation too, so e does not depend on the logging rate."""
    model = mjcf_drop("box", "box", "0.05 0.05 0.05", 0.6, euler="30 0 0")
    coarse = load_log(record_model("box_edge", model, ["stop.max_time=0.6", "logging.every=25"]))
    fine, sparse = analyze_run(edge_box).bounces, analyze_run(coarse).bounces
    assert fine.height == sparse.height >= 3
    for col in ("v_in_mps", "v_out_mps", "e_velocity"):
        np.testing.assert_allclose(sparse[col], fine[col], rtol=0, atol=1e-9, err_msg=col)


STATIC_SCENE = """<mujoco><worldbody><geom name="floor" type="plane" size="5 5 .1"/>
  <body name="brick" pos="0 0 .1"><geom name="brick" type="box" size=".1 .1 .1"/></body>
</worldbody></mujoco>"""


def test_a_model_where_nothing_moves_is_recorded_analyzed_and_replayed(tmp_path, capsys):
    """A brick welded to the world on a plane (dm_control's arenas and lego brick, lqr.xml):
    MuJoCo loads and steps it, so impactlab records it (no body, a constant energy), and the
    record, the analysis (with figures) and the replay say that nothing moves, with no error."""
    from impactlab.logs.format import NOTHING_MOVES

    model = tmp_path / "static.xml"
    model.write_text(STATIC_SCENE)
    logs, results = tmp_path / "logs", tmp_path / "results"
    assert main(["record", str(model), "--duration", "0.1", "-o", str(logs)]) == 0
    (path,) = logs.glob("*.mcap")
    assert f"warning: {path.stem}: {NOTHING_MOVES}" in capsys.readouterr().out
    run = load_log(path)
    assert not run.partial and run.outcome == "completed" and not run.bodies
    assert run.energy.height == 51  # every step of 0.1 s at 2 ms
    assert np.ptp(run.energy["total"].to_numpy()) == 0.0
    assert run.contacts.is_empty()  # the brick and the floor are one rigid body: the world
    assert main(["analyze", str(logs), "-o", str(results)]) == 0
    capsys.readouterr()
    report = (results / "report.md").read_text()
    assert f"In every run {NOTHING_MOVES}" in report and "no figure to draw" in report
    assert "--no-figures" not in report  # figures were asked for: none has anything to show
    assert "Not answered: nothing moves in any run." in report
    runs = pl.read_parquet(results / "runs.parquet")
    assert runs["n_bodies"].to_list() == [0] and runs["outcome"].to_list() == ["completed"]
    assert NOTHING_MOVES in runs["warnings"][0]
    assert main(["replay", str(path), "-o", str(tmp_path / "static.rrd")]) == 0
    capsys.readouterr()
    import rerun as rr

    texts = [
        text[0]
        for chunk in rr.chunk.RrdReader(tmp_path / "static.rrd").stream()
        if not chunk.is_static and chunk.entity_path.endswith("/events/log")
        for text in chunk.to_record_batch().column("TextLog:text").to_pylist()
    ]
    assert NOTHING_MOVES in texts
    # every body (none) is at rest: the at-rest rule ends it after its rest time
    rest = ["--set", "stop.at_rest=true", "-o", str(tmp_path / "rest")]
    assert main(["record", str(model), "--duration", "0.1", *rest]) == 0
    capsys.readouterr()
    (path,) = (tmp_path / "rest").glob("*.mcap")
    assert load_log(path).meta["reason"] == "bodies at rest"
