"""Runs analyzed together (`analyze_runs`) give each run the analysis it gets alone.

The small tables of a batch are computed in one set of frame operations keyed by run_id;
the results must not depend on which runs share a batch. Group aggregates may sum in
another order, so floats are compared to 1e-12 relative.
"""

from __future__ import annotations

import dataclasses
import math

import polars as pl
import pytest
from paths import GOLDEN
from polars.testing import assert_frame_equal
from specs import collision, drop, toml

from impactlab.analyze import batch as batch_module
from impactlab.analyze.batch import analyze_some, batches, distinct_batches
from impactlab.analyze.measure.analysis import RunAnalysis, analyze_run, analyze_runs
from impactlab.analyze.tables import decimate as outputs
from impactlab.errors import LogError
from impactlab.logs.load import load_log

LOGS = sorted((GOLDEN / "logs").glob("*.mcap"))
FRAMES = ("states", "intervals", "energy", "phases", "bounces", "collisions")


def same(a: RunAnalysis, b: RunAnalysis) -> None:
    for name in FRAMES:
        assert_frame_equal(getattr(a, name), getattr(b, name), rel_tol=1e-12, abs_tol=1e-15)
    assert a.summary.keys() == b.summary.keys()
    for key, value in a.summary.items():
        other = b.summary[key]
        if isinstance(value, float) and isinstance(other, float):
            assert math.isclose(value, other, rel_tol=1e-12, abs_tol=1e-15), key
        else:
            assert value == other, key


@pytest.fixture(scope="module")
def alone():
    assert len(LOGS) >= 5  # drops, a box on its edge, collisions
    return [analyze_run(load_log(p)) for p in LOGS]


def test_a_batch_equals_each_run_alone(alone):
    together = analyze_runs([load_log(p) for p in LOGS])
    assert [a.run.run_id for a in together] == [a.run.run_id for a in alone]
    for a, b in zip(together, alone, strict=True):
        same(a, b)
    # the batch has bounces and collisions of several runs: each run keeps its own
    assert sum(a.bounces.height for a in together) > max(a.bounces.height for a in together)
    assert sum(a.collisions.height > 0 for a in together) >= 2


def test_batch_order_does_not_matter(alone):
    together = analyze_runs([load_log(p) for p in reversed(LOGS)])
    for a, b in zip(reversed(together), alone, strict=True):
        same(a, b)


def test_an_unreadable_run_fails_alone(alone):
    runs = [load_log(p) for p in LOGS]
    runs[1] = dataclasses.replace(runs[1], meta={})
    out = analyze_runs(runs)
    assert isinstance(out[1], LogError)
    assert "no impactlab.run metadata" in out[1].problem
    for i, (a, b) in enumerate(zip(out, alone, strict=True)):
        if i != 1:
            same(a, b)


def test_repeated_run_ids_go_to_separate_batches(tmp_path):
    run = load_log(LOGS[0])
    with pytest.raises(ValueError, match="distinct run ids"):
        analyze_runs([run, load_log(LOGS[0])])
    twice = [(0, run), (1, load_log(LOGS[1])), (2, load_log(LOGS[0])), (3, load_log(LOGS[0]))]
    groups = distinct_batches(twice)
    assert [[i for i, _ in g] for g in groups] == [[0, 1], [2], [3]]
    copy = tmp_path / "copy.mcap"
    copy.write_bytes(LOGS[0].read_bytes())
    items = [(LOGS[0], LOGS[0]), (copy, copy)]
    results = analyze_some(items, None)
    assert [r.error for r in results] == [None, None]
    a, b = (r.analysis for r in results)
    assert a is not None and b is not None
    assert_frame_equal(a.bounces, b.bounces)
    assert str(b.run.path) == str(copy)


def test_batches_are_bounded_and_consecutive(tmp_path, monkeypatch):
    files = []
    for i in range(10):
        f = tmp_path / f"{i}.mcap"
        f.write_bytes(b"x" * (100 if i != 4 else 1000))
        files.append((f, f))
    monkeypatch.setattr(batch_module, "BATCH_LOGS", 3)
    monkeypatch.setattr(batch_module, "BATCH_BYTES", 500)
    assert batches(files) == [[0, 1, 2], [3], [4], [5, 6, 7], [8, 9]]
    # an executor's workers all get work: `parts` batches when there are logs enough
    assert batches(files[:6], parts=6) == [[i] for i in range(6)]
    assert batches(files[5:], parts=2) == [[0, 1], [2, 3, 4]]
    assert len(batches(files, parts=20)) == 10
    assert batches([]) == []


def test_a_missing_file_in_a_batch_is_its_own_error(tmp_path):
    gone = tmp_path / "gone.mcap"
    items = [(LOGS[0], LOGS[0]), (gone, gone), (LOGS[1], LOGS[1])]
    results = analyze_some(items, None)
    assert results[0].analysis is not None and results[2].analysis is not None
    assert results[1].analysis is None and results[1].error is not None
    assert results[1].error[0] == str(gone)


FALL = toml(drop("batch_fall", gravity=[0.0, 0.0, -9.81], plane=False, max_time=0.2))
REST = toml(drop("batch_rest", z=0.1, max_time=0.2))
MISS = toml(
    collision(
        "batch_miss",
        names=("ball1", "ball2"),
        x=1.0,
        z=1.0,
        vel=(1.0, 0.0),
        max_time=0.1,
        separation=0.01,
    )
)


@pytest.mark.slow
def test_runs_of_every_kind_together(record_spec):
    """No ground and no contact, a ball resting from the start (no bounce, with the reason),
    a collision that never happens (its reason row), with bounces and collisions."""
    paths = [
        *record_spec("batch_fall", FALL),
        *record_spec("batch_rest", REST),
        *record_spec("batch_miss", MISS),
        *LOGS,
    ]
    alone = [analyze_run(load_log(p)) for p in paths]
    together = analyze_runs([load_log(p) for p in paths])
    for a, b in zip(together, alone, strict=True):
        same(a, b)
    fall, rest, miss = together[:3]
    assert fall.intervals.is_empty() and fall.bounces.is_empty() and fall.phases.height == 1
    assert rest.bounces.height == 1 and "at rest" in rest.bounces["note"][0]
    assert miss.collisions.height == 1 and "never happened" in miss.collisions["note"][0]


def test_energy_decimated_from_blocks_as_by_groups(monkeypatch):
    """Each run's energy table is decimated from its bodies' blocks (numpy): the rows a
    group-by over (run, body) keeps, also for a table not by body (the general path)."""
    monkeypatch.setattr(outputs, "ENERGY_ROWS_PER_RUN", 50)
    for a in analyze_runs([load_log(p) for p in LOGS]):
        fast = outputs.with_decimated_energy(a)
        assert fast.energy_logged[1] > 50 and fast.energy.height < a.energy.height
        assert_frame_equal(fast.energy, outputs.decimate(a.energy, max_rows=50))
        shuffled = dataclasses.replace(a, energy=a.energy.sort("t_ns", "body"))
        general = outputs.with_decimated_energy(shuffled)
        assert general.energy_logged == fast.energy_logged
        assert_frame_equal(general.energy, outputs.decimate(shuffled.energy, max_rows=50))


def test_runs_whose_frames_differ_in_type_are_analyzed_as_alone(alone):
    """A log whose episodes have another column type (a foreign producer): the same
    results as each run analyzed alone."""
    runs = [load_log(p) for p in LOGS]
    drops = [i for i, p in enumerate(LOGS) if p.stem.startswith("drop_")]
    assert len(drops) == 2  # two runs of one kind (a ball on the plane): stacked together
    odd = runs[drops[0]]
    runs[drops[0]] = dataclasses.replace(
        odd, impacts=odd.impacts.with_columns(pl.col("steps").cast(pl.Int32))
    )
    for a, b in zip(analyze_runs(runs), alone, strict=True):
        same(a, b)


def bounce(name: str, integrator: str, g: tuple[float, float], mass: float, every: int) -> str:
    """A ball tossed sideways 0.4 m up, gravity (g_x, g_z) in m/s^2: two bounces."""
    return toml(
        drop(
            name,
            z=0.4,
            radius=0.05,
            mass=mass,
            vel=[0.3, 0.0, 0.0],
            timestep=0.0005,
            integrator=integrator,
            gravity=[g[0], 0.0, g[1]],
            contact={"condim": 1, "solref": [0.01, 0.1]},
            max_time=1.2,
            bounces=2,
            every=every,
        )
    )


def test_runs_of_different_physics_together(record_spec):
    """Gravity (tilted, weaker), integrators and logging strides differ per run: each run's
    own are used in the batch (the apexes depend on them, v_min on gravity and timestep)."""
    cases = [
        dict(name="batch_euler", integrator="Euler", g=(0.0, -9.81), mass=1.0, every=1),
        dict(name="batch_rk4", integrator="RK4", g=(0.0, -9.81), mass=2.0, every=3),
        dict(name="batch_moon", integrator="implicitfast", g=(0.0, -1.62), mass=1.0, every=2),
        dict(name="batch_tilt", integrator="Euler", g=(2.0, -9.6), mass=0.5, every=1),
    ]
    paths = [p for c in cases for p in record_spec(c["name"], bounce(**c))]
    alone = [analyze_run(load_log(p)) for p in paths]
    together = analyze_runs([load_log(p) for p in paths])
    for a, b in zip(together, alone, strict=True):
        same(a, b)
    v_min = [a.intervals["v_min_mps"][0] for a in together]
    physics = {(c["g"], c.get("timestep")) for c in cases}
    assert len(set(v_min)) == len(physics)  # each run's own gravity and timestep
    assert all(a.bounces.filter(pl.col("complete")).height >= 1 for a in together)


def test_bodies_logged_at_different_times_sum_by_time():
    """A damaged log whose bodies are not logged at the same times: its "total" rows are the
    sums of the bodies' energies at each time either logged (a group-by), in a batch too."""
    runs = [load_log(p) for p in LOGS]
    i = next(k for k, r in enumerate(runs) if len(r.bodies) == 2)
    run = runs[i]
    first = next(iter(run.bodies))
    bodies = dict(run.bodies)
    bodies[first] = bodies[first].gather_every(2)  # every other row of one body lost
    runs[i] = dataclasses.replace(run, bodies=bodies)
    a = analyze_runs(runs)[i]
    parts = a.energy.filter(pl.col("body") != "total")
    expected = parts.group_by("t_ns", maintain_order=True).agg(pl.col("total_J").sum()).sort("t_ns")
    total = a.energy.filter(pl.col("body") == "total").sort("t_ns")
    assert total.height == expected.height > parts.filter(pl.col("body") == first).height
    assert_frame_equal(total.select("t_ns", "total_J"), expected, rel_tol=1e-12, abs_tol=1e-15)
