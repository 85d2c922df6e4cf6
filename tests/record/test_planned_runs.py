"""A planned sweep holds its grid, not its runs: nothing per run is retained by `plan`.

The runs are built again when read (`impactlab.record.planner.PlannedRuns`); they are the
runs a list would hold, in the same order, and recording reads each once per pass.
"""

from __future__ import annotations

import gc
from pathlib import Path

import pytest

from impactlab.errors import SpecError
from impactlab.record import plan
from impactlab.record.planner import PlannedRun
from impactlab.record.spec import RunSpec
from impactlab.record.sweep import SpecSweep

SPEC = """
name = "lazy"
[bodies.ball]
radius = 0.1
mass = 1.0
pos = [0.0, 0.0, 1.0]
[stop]
max_time = 0.01
[sweep]
"ball.mass" = [{masses}]
"ball.radius" = [0.1, 0.2, 0.3]
"""


def _spec(tmp_path: Path, masses: int) -> Path:
    path = tmp_path / f"lazy_{masses}.toml"
    path.write_text(SPEC.format(masses=", ".join(f"{1 + 0.5 * i:g}" for i in range(masses))))
    return path


def _alive() -> tuple[int, int]:
    """The `RunSpec` and `PlannedRun` objects alive, after one collection (the costly part in
    a whole session's heap: one for both counts)."""
    gc.collect()
    kinds = (RunSpec, PlannedRun)
    alive = [o for o in gc.get_objects() if isinstance(o, kinds)]
    return sum(isinstance(o, RunSpec) for o in alive), sum(isinstance(o, PlannedRun) for o in alive)


def test_plan_keeps_no_run_of_a_sweep(tmp_path):
    before = _alive()
    runs = plan(_spec(tmp_path, 100))
    assert len(runs) == 300
    assert _alive() == before  # validated, then dropped


def test_runs_read_by_index_equal_the_runs_in_order(tmp_path):
    path = _spec(tmp_path, 4)
    runs = plan(path)
    listed = list(runs)
    assert [r.spec for r in listed] == list(SpecSweep.read(path).iter_runs())  # the grid's order
    assert [runs[i] for i in range(len(runs))] == listed
    assert runs[-1] == listed[-1] and runs[2:5] == listed[2:5]
    assert len({r.info.run_id for r in listed}) == 12
    with pytest.raises(IndexError):
        runs[12]


def test_a_bad_point_fails_at_plan_time(tmp_path):
    path = _spec(tmp_path, 3)
    path.write_text(path.read_text().replace('"ball.mass" = [1, ', '"ball.mass" = [1, -2, '))
    with pytest.raises(SpecError, match="mass"):
        plan(path)


@pytest.mark.slow  # six runs recorded by forked workers: over 2 s
def test_recording_holds_no_planned_run_in_the_driver(tmp_path):
    """While forked workers record a sweep, the driver holds its runs as indices: when each
    run's result arrives, at most one planned run (the last one read, with its resolved
    spec) is alive here, not one per run."""
    from impactlab.executors.processes import can_fork
    from impactlab.record.recorder import record_runs

    assert can_fork()
    runs = plan(_spec(tmp_path, 2))  # 6 runs
    alive: list[tuple[int, int]] = []

    def progress(event) -> None:
        if event.line is not None and event.done:
            alive.append(_alive())

    result = record_runs(runs, tmp_path / "logs", threads=2, progress=progress)
    assert len(result) == 6 and not result.failed
    assert len(alive) >= 6 and max(max(a) for a in alive) <= 1, alive
