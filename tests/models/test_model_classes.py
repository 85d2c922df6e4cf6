"""Issue 35's minimal models, one class each, against MuJoCo's own numbers.

Each model lies in benchmarks/zoo/models (the big mesh is generated here); `zoo_run` records,
analyzes (with figures and a report) and replays it with impactlab and runs plain MuJoCo on
the same file (benchmarks/zoo/oracle.py: energies, the work of each force, contact episodes
found at every step). Speeds are compared to 1e-6 m/s, works to 1e-9 of the run's energy
scale, and a number a person reads (report.md, the collisions table, the .rrd) as written.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import polars as pl
import pytest
import rerun as rr
from zoo_models import ZOO, zoo

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.cli import main
from impactlab.logs.load import load_log
from impactlab.replay.convert import run_prefix

pytestmark = pytest.mark.slow

SPEED_ATOL = 1e-6  # m/s, an onset or release speed against MuJoCo's
WORK_RTOL = 1e-9  # of the run's energy scale, a work against MuJoCo's
ISSUE_ONSET_ATOL = 0.005  # s, MuJoCo's onset here against the issue's (another MuJoCo version)


def episode(run, party1: str, party2: str, *, truth: bool = True):
    """The first episode of a pair (either order), MuJoCo's or impactlab's."""
    episodes = (run.truth if truth else run.side.run).episodes
    found = [e for e in episodes if {e.party1, e.party2} == {party1, party2}]
    assert found, f"no episode of {party1} and {party2}"
    return found[0]


def final_work(run, kind: str) -> tuple[float, float, float]:
    """(MuJoCo's, impactlab's, tolerance) cumulative work of one kind at the last logged step, J."""
    tol = WORK_RTOL * run.truth.energy_scale
    return float(run.truth.work[kind][-1]), float(run.side.run.work[kind][-1]), tol


def section(report: str, title: str) -> str:
    """The text of the report's section whose heading starts with `title`, to the next one."""
    match = re.search(rf"^## {re.escape(title)}.*?(?=^## |\Z)", report, re.M | re.S)
    assert match, f"no section {title!r} in the report"
    return match.group(0)


def static_entities(rrd: Path) -> dict[str, dict[str, object]]:
    """Every static component of a recording by entity path (Rerun's own reader)."""
    out: dict[str, dict[str, object]] = {}
    for chunk in rr.chunk.RrdReader(rrd).stream():
        if chunk.is_static:
            row = chunk.to_record_batch().to_pylist()[-1]
            out.setdefault(chunk.entity_path, {}).update({k: v for k, v in row.items() if ":" in k})
    return out


def last_temporal(rrd: Path, entity: str, component: str) -> object:
    """The value of a component at the recording's last time on an entity."""
    latest, value = -1, None
    for chunk in rr.chunk.RrdReader(rrd).stream():
        if chunk.is_static or chunk.entity_path != entity:
            continue
        batch = chunk.to_record_batch()
        if component not in batch.schema.names:
            continue
        times = batch.column("sim_time").cast("int64").to_pylist()
        values = batch.column(component).to_pylist()
        i = int(np.argmax(times))
        if times[i] >= latest:
            latest, value = times[i], values[i]
    assert value is not None, f"no {component} on {entity}"
    return value


def plain_mujoco(path: Path, nsteps: int) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The model after nsteps of a bare mj_step loop, its positions computed at that state
    (mj_step leaves those of the step's start)."""
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    for _ in range(nsteps):
        mujoco.mj_step(m, d)
    mujoco.mj_forward(m, d)
    return m, d


# ---- geoms on massless bodies -------------------------------------------------------------


def test_a_foot_on_a_massless_body_lands_at_mujocos_time_and_speed(zoo_run):
    run = zoo_run("models/massless_foot.xml", 1)
    want = episode(run, "leg", "floor")
    assert want.onset_time == pytest.approx(0.442, abs=ISSUE_ONSET_ATOL)
    got = episode(run, "leg", "floor", truth=False)
    assert got.onset_step == want.onset_step
    assert got.approach_speed == pytest.approx(want.approach_speed, abs=SPEED_ATOL)
    report = run.report
    assert "no run has a ground" not in report
    row = pl.read_parquet(run.folder / "results" / "runs.parquet").row(0, named=True)
    assert row["ground"] and row["first_impact_speed_mps"] == pytest.approx(
        want.approach_speed, abs=SPEED_ATOL
    )


# ---- flexes -----------------------------------------------------------------------------------


def test_a_flex_contacts_the_floor_from_mujocos_onset_and_its_work_is_booked(zoo_run):
    run = zoo_run("models/flexcomp_drop.xml", 1)
    want = episode(run, "flex cube", "floor")
    assert want.onset_time == pytest.approx(0.283, abs=ISSUE_ONSET_ATOL)
    got = episode(run, "flex cube", "floor", truth=False)
    assert (got.onset_step, got.release_step) == (want.onset_step, want.release_step)
    assert got.approach_speed == pytest.approx(want.approach_speed, abs=SPEED_ATOL)
    # an impact is found: the analysis' episode of the flex arrived faster than v_min
    analysis = analyze_run(load_log(run.log))
    impacts = analysis.intervals.filter(pl.col("impact"))
    assert impacts.height == 1 and "cube" in {impacts["body"][0], impacts["other"][0]}
    # the contact's work is booked (the issue: "the contacts remove 0 J") and is MuJoCo's
    theirs, ours, tol = final_work(run, "contact_normal")
    assert theirs < -1.0 and ours == pytest.approx(theirs, abs=tol)
    assert analysis.summary["work_contact_normal_J"] == pytest.approx(theirs, abs=tol)
    assert "not explained by the integrator" not in run.report


def test_a_flex_is_drawn_in_the_replay_where_mujoco_has_it(zoo_run):
    run = zoo_run("models/flexcomp_drop.xml", 1)
    m, d = plain_mujoco(run.path, run.truth.nsteps)
    prefix = run_prefix(load_log(run.log).run_id)
    entity = f"{prefix}/world/flexes/cube"
    static = static_entities(run.rrd)[entity]
    triangles = np.asarray(static["Mesh3D:triangle_indices"]).reshape(-1, 3)
    assert triangles.shape[0] == int(m.flex_shellnum[0]) > 0
    vertices = np.asarray(last_temporal(run.rrd, entity, "Mesh3D:vertex_positions"))
    np.testing.assert_allclose(vertices.reshape(-1, 3), d.flexvert_xpos, atol=1e-6)  # float32


def test_the_report_says_what_a_flexs_contact_removed(zoo_run):
    run = zoo_run("models/flexcomp_drop.xml", 1)
    step1 = section(run.report, "Step 1")
    assert "no contact loses energy" not in step1
    assert "no run has a ground" not in step1


# ---- bodies touching at t = 0 ---------------------------------------------------------------


def test_bodies_touching_at_the_start_are_analyzed_and_said_to(zoo_run, tmp_path, capsys):
    run = zoo_run("models/stacked_boxes.xml", 1)
    assert episode(run, "lower", "upper").onset_vn is None  # MuJoCo: touching at t = 0
    assert main(["analyze", str(run.log), "-o", str(tmp_path / "results")]) == 0
    capsys.readouterr()
    collisions = pl.read_parquet(tmp_path / "results" / "collisions.parquet")
    row = collisions.filter(pl.col("body1").is_in(["lower", "upper"])).row(0, named=True)
    assert row["impact_t_s"] == 0.0
    assert "touch from the start" in row["note"]
    assert row["e_velocity"] is None and row["e_energy"] is None and not row["complete"]


def test_a_pair_touching_from_the_start_has_no_before_state(zoo_run):
    run = zoo_run("models/stacked_boxes.xml", 1)
    collisions = pl.read_parquet(run.folder / "results" / "collisions.parquet")
    row = collisions.filter(pl.col("impact_t_s") == 0.0).row(0, named=True)
    numbers = {k: v for k, v in row.items() if isinstance(v, float)}
    assert all(math.isfinite(v) for v in numbers.values()), numbers
    before = [k for k in row if "before" in k or "elastic" in k or "inelastic" in k]
    assert all(row[k] is None for k in before), {k: row[k] for k in before}


# ---- a robot resting into the floor, a centre of mass outside its geoms ----------------------


def test_a_robot_sunk_into_the_floor_is_recorded_and_analyzed(zoo_run, tmp_path, capsys):
    run = zoo_run("models/sunk_robot.xml", 1)
    thighs = [episode(run, f"{leg}_thigh", "floor") for leg in ("front", "rear")]
    assert all(e.onset_vn is None and e.max_penetration > 0.009 for e in thighs)  # MuJoCo's
    path = run.path
    assert main(["record", str(path), "--duration", "0.05", "-o", str(tmp_path / "logs")]) == 0
    assert main(["analyze", str(tmp_path / "logs"), "-o", str(tmp_path / "results")]) == 0
    capsys.readouterr()
    (log,) = (tmp_path / "logs").glob("*.mcap")
    info = load_log(log).body_info
    # the thigh's centre of mass is 5 cm above its capsule (radius 2 cm, from 0 to -20 cm):
    # turned over, it rests 3 cm below the surface it touches
    assert info["front_thigh"].rest_height_m == pytest.approx(-0.03, abs=1e-12)
    assert info["trunk"].rest_height_m == pytest.approx(0.04, abs=1e-12)  # the box's thinnest
    summary = json.loads((tmp_path / "results" / "summary.json").read_text())
    assert summary  # written: the analysis refused nothing the recorder wrote


# ---- qpos0 outside the joint limits ------------------------------------------------------------


def test_limits_violated_at_the_start_are_a_force_not_an_instability(zoo_run):
    run = zoo_run("models/limits_violated.xml", 1)
    truth, ours = run.truth, run.side.run
    assert truth.stopped is None and not any(truth.warnings.values())  # MuJoCo runs it all
    log = load_log(run.log)
    assert log.outcome == "completed" and not any("unstable" in w for w in log.warnings)
    assert ours.step[-1] == truth.step[-1] == truth.nsteps
    # the limits push the legs into range: the energy jumps, by less than their work (the
    # damping takes the rest)
    jump = int(np.argmax(ours.energy))
    gain = ours.energy[jump] - ours.energy[0]
    assert 0.5 < gain <= ours.work["limit"][jump]
    np.testing.assert_allclose(
        ours.work["limit"], truth.work["limit"], atol=WORK_RTOL * truth.energy_scale
    )
    # the residual (what no force explains) stays a small part of it
    assert np.max(np.abs(ours.residual)) < 0.1 * truth.work["limit"].max()
    assert "unstable" not in run.report.lower()


# ---- losses booked to the force that does them ------------------------------------------------


def test_damping_and_contact_work_are_mujocos(zoo_run):
    run = zoo_run("models/all_forces.xml", 1)
    for kind in ("damper", "contact_normal", "contact_friction", "limit", "friction_loss"):
        theirs, ours, tol = final_work(run, kind)
        assert ours == pytest.approx(theirs, abs=tol), kind
    assert final_work(run, "damper")[0] < -0.05 and final_work(run, "contact_normal")[0] < -0.05


def test_a_loss_that_is_all_damping_is_booked_to_damping_not_drift(zoo_run):
    run = zoo_run("models/damped_pendulum.xml", 1)
    assert not run.truth.episodes  # it never touches anything
    damping, ours, tol = final_work(run, "damper")
    assert damping < -0.1 and ours == pytest.approx(damping, abs=tol)
    row = pl.read_parquet(run.folder / "results" / "runs.parquet").row(0, named=True)
    assert row["work_damping_J"] == pytest.approx(damping, abs=tol)
    assert row["contact_loss_sum_J"] == 0 and row["work_contact_normal_J"] == 0
    # the drift is the integrator's residual, not the damper's loss
    assert row["residual_J"] == pytest.approx(run.truth.residual[-1], abs=tol)
    assert abs(row["flight_drift_J"]) < 0.1 * abs(damping)
    assert "not a physical loss" not in run.report


def test_the_report_names_damping_as_where_the_energy_went(zoo_run):
    step1 = section(zoo_run("models/damped_pendulum.xml", 1).report, "Step 1")
    assert "damping" in step1.lower()
    assert not re.search(r"at the contacts [^.]*gone", step1)


@pytest.mark.parametrize("name", ["models/damped_pendulum.xml", "models/all_forces.xml"])
def test_the_report_calls_the_residual_the_integrators(zoo_run, name):
    step1 = section(zoo_run(name, 1).report, "Step 1")
    assert "something else acts" not in step1


# ---- impacts of jointed bodies at any logging stride -------------------------------------------


def test_a_jointed_impact_is_the_same_at_every_logging_stride(zoo_run):
    runs = {every: zoo_run("models/jointed_boxes.xml", every) for every in (1, 5)}
    want = episode(runs[1], "striker", "target")
    assert want.approach_speed > 1.0 and want.restitution is not None
    impacts, speeds = {}, {}
    for every, run in runs.items():
        got = episode(run, "striker", "target", truth=False)
        speeds[every] = (got.approach_speed, got.separation_speed)
        assert (got.onset_step, got.release_step) == (want.onset_step, want.release_step)
        assert got.approach_speed == pytest.approx(want.approach_speed, abs=SPEED_ATOL)
        assert got.separation_speed == pytest.approx(want.separation_speed, abs=SPEED_ATOL)
        collisions = pl.read_parquet(run.folder / "results" / "collisions.parquet")
        impacts[every] = collisions.select("impact_t_s", "v1n_before_mps", "e_velocity").row(0)
        assert impacts[every][2] == pytest.approx(want.restitution, abs=1e-4)
    np.testing.assert_allclose(speeds[1], speeds[5], rtol=0, atol=1e-9)
    np.testing.assert_allclose(impacts[1], impacts[5], rtol=0, atol=1e-9)


# ---- includes ---------------------------------------------------------------------------------


def test_a_nested_include_is_loaded(zoo_run, tmp_path, capsys):
    """parts/leg.xml includes foot.xml beside itself; MuJoCo finds it, so does the recorder."""
    scene = ZOO / "models" / "nested_include" / "scene.xml"
    assert [beside for _, _, beside in zoo.include_tree(scene)] == [False, True]
    assert main(["record", str(scene), "--duration", "0.05", "-o", str(tmp_path)]) == 0
    capsys.readouterr()
    (log,) = tmp_path.glob("*.mcap")
    assert set(load_log(log).body_info) == {"leg", "foot_body"}
    assert not zoo_run("models/nested_include/scene.xml", 1).failed_checks()


# ---- a large mesh --------------------------------------------------------------------------


def cube_surface(n: int, half: float) -> tuple[np.ndarray, np.ndarray]:
    """A cube's surface (half side `half`, m) as n x n squares per side, two triangles each:
    vertices (6 n^2 + 2, 3) and faces (12 n^2, 3), outward."""
    grid = np.arange(n + 1)
    i, j, k = np.meshgrid(grid, grid, grid, indexing="ij")
    surface = (i % n == 0) | (j % n == 0) | (k % n == 0)
    index = np.full((n + 1,) * 3, -1, np.int64)
    index[surface] = np.arange(surface.sum())
    vertices = np.stack([i[surface], j[surface], k[surface]], 1) * (2 * half / n) - half
    a, b = (x.ravel() for x in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    faces = []
    for axis in range(3):
        u, v = (x for x in range(3) if x != axis)
        for side in (0, n):

            def corner(du: int, dv: int, axis=axis, u=u, v=v, side=side) -> np.ndarray:
                point = np.zeros((a.size, 3), np.int64)
                point[:, axis], point[:, u], point[:, v] = side, a + du, b + dv
                return index[point[:, 0], point[:, 1], point[:, 2]]

            q = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)]
            triangles = np.concatenate([np.stack(q[:3], 1), np.stack([q[0], q[2], q[3]], 1)])
            outward = (side == n) == (u == (axis + 1) % 3)  # e_u x e_v along the outer normal
            faces.append(triangles if outward else triangles[:, ::-1])
    return vertices, np.concatenate(faces)


PEAK_RSS_MB = 1500  # generous: the recorder with Python, MuJoCo and polars takes about 300 MB


def test_a_large_mesh_is_recorded_in_bounded_memory_with_its_rest_height(tmp_path):
    """A block of 101,568 faces and 50,786 vertices (its convex hull: 8 vertices); the issue's
    recorder took every vertex times every face normal (a 40 GB array here)."""
    half = 0.2
    vertices, faces = cube_surface(92, half)
    assert len(faces) >= 50_000
    points = vertices[faces]
    normals = np.cross(points[:, 1] - points[:, 0], points[:, 2] - points[:, 0])
    assert np.all(np.einsum("ij,ij->i", normals, points.mean(axis=1)) > 0)  # outward
    with open(tmp_path / "block.obj", "w") as obj:
        obj.writelines(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in vertices)
        obj.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces)
    (tmp_path / "big_mesh.xml").write_text(
        '<mujoco model="big_mesh"><asset><mesh name="block" file="block.obj"/></asset>'
        '<worldbody><geom name="floor" type="plane" size="5 5 .1"/><body name="block" '
        'pos="0 0 .3" euler="0 0 30"><freejoint/><geom type="mesh" mesh="block"/></body>'
        "</worldbody></mujoco>"
    )
    script = (  # VmHWM: unlike ru_maxrss, not inherited over exec from pytest's worker
        "import resource, sys\nfrom impactlab.cli import main\n"
        "code = main(['record', 'big_mesh.xml', '--duration', '0.02', '-o', 'logs'])\n"
        "own = next(int(l.split()[1]) for l in open('/proc/self/status') if l[:6] == 'VmHWM:')\n"
        "peak = max(own, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
        "print('PEAK_KB', peak)\nsys.exit(code)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "Traceback" not in done.stderr and "MemoryError" not in done.stderr
    peak = re.search(r"PEAK_KB (\d+)", done.stdout)
    assert peak is not None, done.stdout
    assert int(peak.group(1)) < PEAK_RSS_MB * 1024, f"peak RSS {int(peak.group(1)) >> 10} MB"
    (log,) = (tmp_path / "logs").glob("*.mcap")
    # its centre of mass rests half a side above the floor, on any face (MuJoCo keeps the
    # vertices as float32: 0.2 is 0.2000000030)
    assert load_log(log).body_info["block"].rest_height_m == pytest.approx(half, abs=1e-8)


# ---- e above 1 ------------------------------------------------------------------------------


def test_e_above_one_in_a_collision_is_explained(zoo_run):
    run = zoo_run("models/tumbling_box.xml", 1)
    over = [e for e in run.truth.episodes if e.restitution is not None and e.restitution > 1]
    assert [{e.party1, e.party2} for e in over] == [{"platform", "box"}]  # MuJoCo's
    collisions = pl.read_parquet(run.folder / "results" / "collisions.parquet")
    rows = collisions.filter(pl.col("e_velocity") > 1)
    assert rows.height == 1
    row = rows.row(0, named=True)
    assert row["e_velocity"] == pytest.approx(over[0].restitution, abs=1e-4)
    assert row["impact_t_s"] == pytest.approx(over[0].onset_time, abs=1e-9)
    assert row["note"].startswith(f"e_velocity {row['e_velocity']:.3g} is outside [0, 1]")
    assert "the model's other forces:" in row["note"]


# ---- what the replay draws -----------------------------------------------------------------


def test_a_mocap_bodys_geom_is_drawn_where_mujoco_has_it(zoo_run):
    run = zoo_run("models/mocap_platform.xml", 1)
    m, d = plain_mujoco(run.path, run.truth.nsteps)
    static = static_entities(run.rrd)
    (drawn,) = [
        p for p, c in static.items() if p.endswith("/platform") and "Boxes3D:half_sizes" in c
    ]
    half = np.asarray(static[drawn]["Boxes3D:half_sizes"]).reshape(-1, 3)[0]
    np.testing.assert_allclose(half, m.geom("platform").size, rtol=1e-6)
    if "/world/static/" in drawn:  # drawn once, where the mocap body holds it all run long
        at = np.asarray(static[drawn]["Transform3D:translation"]).reshape(-1, 3)[0]
        np.testing.assert_allclose(at, d.geom("platform").xpos, atol=1e-6)  # float32


def test_an_sdf_geom_is_drawn_as_mujoco_meshes_it(zoo_run):
    """The SDF plugin ships in MuJoCo's wheel (libsdf_plugin: torus, bowl, nut, bolt, gear)."""
    run = zoo_run("models/sdf_torus.xml", 1)
    m = mujoco.MjModel.from_xml_path(str(run.path))
    assert int(m.geom_type[m.geom("ring").id]) == int(mujoco.mjtGeom.mjGEOM_SDF)
    prefix = run_prefix(load_log(run.log).run_id)
    static = static_entities(run.rrd)[f"{prefix}/world/bodies/ring/geoms/ring"]
    faces = int(m.mesh_facenum[m.geom_dataid[m.geom("ring").id]])
    assert len(static["Mesh3D:vertex_positions"]) == 3 * faces > 0
    assert episode(run, "ring", "floor").onset_vn is not None  # it lands
    assert not run.failed_checks()


def test_the_replay_has_series_only_for_pairs_that_touch(zoo_run):
    run = zoo_run("models/boxes_100.xml", 1)
    pairs = {(e.party1, e.party2) for e in run.truth.episodes}
    nbody = load_log(run.log).body_info
    assert 20 < len(pairs) < len(nbody) * (len(nbody) + 1) // 2
    prefix = f"{run_prefix(load_log(run.log).run_id)}/series/contact_force/"
    series = {
        p.removeprefix(prefix)
        for p in static_entities(run.rrd)
        if p.startswith(prefix) and "/" not in p.removeprefix(prefix)
    }
    names = [{rr.escape_entity_path_part(f"{a}-{b}"), rr.escape_entity_path_part(f"{b}-{a}")}
             for a, b in pairs]  # fmt: skip
    assert len(series) == len(pairs)
    assert all(len(series & both) == 1 for both in names)
