"""Record runs as executor tasks (worker processes, a Ray cluster): small tasks, logs named by hash.

The planned runs are cut into tasks (`task_ranges`); each task records its runs with
batched rollouts and writes their logs straight to the output folder, named by the run's
spec hash and written atomically, so a retried task overwrites its own partial output and
never duplicates a run. A task returns only a `RecordedRun` per run.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TypeVar

from impactlab.executors.base import Executor
from impactlab.executors.processes import ProcessExecutor
from impactlab.logs.writer import remove_stale_partials
from impactlab.progress import Tracker
from impactlab.record.batch import BATCH_RUNS, LogWriteError, record_batches
from impactlab.record.folder import log_path, reusable
from impactlab.record.model import model_from_spec
from impactlab.record.planner import PlannedRun, Subset
from impactlab.record.results import RecordedRun

T = TypeVar("T")

MAX_TASK_RUNS = 16  # runs per task at most: a lost task costs little, results stream in
TASKS_PER_SLOT = 4  # tasks per worker slot at least (when there are enough runs): balance


def portable(run: PlannedRun) -> PlannedRun:
    """The planned run with a picklable `build` (rebuilt from the spec in the task).

    Spec runs rebuild their model from the `RunSpec`; MJCF runs carry their validated model
    (it pickles), so the workers need neither the MJCF file nor the spec file.
    """
    if run.spec is not None:
        build = functools.partial(model_from_spec, run.spec, run.pairs)
    else:
        build = functools.partial(_same, run.build())
    return dataclasses.replace(run, build=build)


def _same(value: T) -> T:
    return value


def task_ranges(runs: int, slots: int, *, max_runs: int = MAX_TASK_RUNS) -> list[range]:
    """Consecutive runs (by index) cut into tasks: about TASKS_PER_SLOT tasks per slot,
    1..max_runs runs each.

    Consecutive runs are mostly points of one sweep, so a task's runs share a batched
    rollout; several tasks per slot keep every slot busy until the end, and a task stays
    small enough that a retry costs little and results stream to the driver.
    """
    size = max(1, min(max_runs, math.ceil(runs / (max(1, slots) * TASKS_PER_SLOT))))
    return [range(i, min(i + size, runs)) for i in range(0, runs, size)]


def record_on(
    executor: Executor,
    runs: Sequence[PlannedRun],
    out_dir: Path,
    tracker: Tracker,
    *,
    overwrite: bool,
    batch_size: int = BATCH_RUNS,
) -> list[RecordedRun]:
    """Record runs (none of them reusable) as tasks of `executor`; returns every run's result.

    Forked workers read their runs from `runs` themselves; other executors get each run
    `portable`. A task that fails (a worker killed) fails its runs whose log is not complete.

    Raises:
        LogWriteError: a log could not be written for a full disk; the logs counted in its
            message are complete.
    """
    ranges = task_ranges(len(runs), executor.slots)
    groups: list[Sequence[PlannedRun]]
    if isinstance(executor, ProcessExecutor) and executor.start == "fork":
        groups = [Subset(runs, r) for r in ranges]  # read in the workers
    else:
        groups = [[portable(runs[i]) for i in r] for r in ranges]
    task = functools.partial(  # absolute: a worker's working folder is not the driver's
        record_batches, out_dir=out_dir.absolute(), batch_size=batch_size, reuse=not overwrite
    )
    out: list[RecordedRun] = []
    for outcome in executor.map(task, groups) if groups else ():
        full = outcome.exception
        if isinstance(full, LogWriteError):  # with the logs its task wrote before
            written = sum(r.status == "recorded" for r in out) + full.written
            raise LogWriteError(full.path, full.problem, written)
        if outcome.ok:
            done = [dataclasses.replace(s, path=out_dir / s.path.name) for s in outcome.value or []]
        else:
            reason = outcome.error or "task failed"
            done = [_lost(out_dir, run, reason, overwrite) for run in groups[outcome.index]]
        for run in done:
            out.append(run)
            count_run(tracker, run)
    return out


def _lost(out_dir: Path, run: PlannedRun, reason: str, overwrite: bool) -> RecordedRun:
    """A run of a task that failed (its worker killed): recorded when its log is complete,
    else failed (what a dead worker was writing removed)."""
    remove_stale_partials(log_path(out_dir, run))
    found = None if overwrite else reusable(out_dir, run)
    if found is not None:
        return dataclasses.replace(found, status="recorded")
    return RecordedRun(run.info.run_id, log_path(out_dir, run), "failed", reason=reason)


def count_run(tracker: Tracker, run: RecordedRun) -> None:
    """Count a finished run and pass its lines on."""
    if run.failed:
        tracker.add("failed")
        tracker.say(f"impactlab: error: {run.run_id}: {run.reason}", "error")
        return
    tracker.add(
        "unstable" if run.unstable else "finished" if run.status == "recorded" else "reused"
    )
    for line in run.lines():
        tracker.say(line)
