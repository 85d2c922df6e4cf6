"""The record job: reuse complete logs, record the rest here or as executor tasks, report.

The runs to record are cut into tasks of consecutive runs (`task_ranges`); each task records
its runs one after the other (`record_logs`) and writes their logs straight to the output
folder, named by the run's spec hash and written atomically, so a retried task overwrites its
own partial output and never duplicates a run. A task returns only a `RecordedRun` per run.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TypeVar

from impactlab.executors.base import Executor, LocalExecutor
from impactlab.executors.processes import ProcessExecutor, available_cpus, can_fork
from impactlab.files import check_writable
from impactlab.logs.writer import PARTIAL_SUFFIX, remove_stale_partials
from impactlab.progress import Progress, Tracker
from impactlab.record.batch import LogWriteError, record_logs
from impactlab.record.folder import log_path, reusable
from impactlab.record.model import model_from_spec
from impactlab.record.planner import PlannedRun, Subset
from impactlab.record.results import RecordedRun, RecordResult
from impactlab.record.work import Work, check_space

T = TypeVar("T")

MAX_TASK_RUNS = 16  # runs per task at most: a lost task costs little, results stream in
TASKS_PER_SLOT = 4  # tasks per worker slot at least (when there are enough runs): balance


def record_runs(
    runs: Sequence[PlannedRun],
    out_dir: Path,
    *,
    executor: Executor | None = None,
    overwrite: bool = False,
    allow_large: bool = False,
    threads: int | None = None,
    progress: Progress | None = None,
) -> RecordResult:
    """Record planned runs into `out_dir`, one log per run; reuse complete logs.

    Args:
        runs: from `impactlab.record.planner.plan`.
        out_dir: the output folder (created); on a cluster, a path every machine sees.
        executor: where the runs are simulated (default: here, on every core: the runs are
            shared among worker processes forked for the job (`ProcessExecutor`), one per
            core, each simulating its runs while it writes their logs; where forking
            is not safe, in this process). Forked workers read their runs from `runs`
            themselves; other executors get each run `portable`.
        overwrite: record again runs whose complete log exists.
        allow_large: record even when the logs to write are estimated larger than the
            free space in `out_dir`.
        threads: worker processes to fork here (default: one per available core; 1: this
            process only).
        progress: receives the job's progress (see `impactlab.progress`); None: silent.

    Returns:
        Every run, in plan order, reused ones included. A task that fails (a worker killed)
        fails its runs whose log is not complete.

    Raises:
        OutputError: the folder cannot be written (before any simulation).
        WorkError: the logs to write would not fit in the folder's free space.
        LogWriteError: a log cannot be written (a full disk); the logs counted in its
            message are complete.
    """
    out_dir = Path(out_dir)
    check_writable(out_dir)
    by_id: dict[str, RecordedRun] = {}
    order: list[str] = []  # every run's id, in plan order
    todo: list[int] = []  # the runs to record, by their index in `runs`
    work = Work()
    # temporary files left in the folder, listed once (not one scan of it per run)
    partials = [n for n in os.listdir(out_dir) if n.endswith(PARTIAL_SUFFIX)]
    for index, run in enumerate(runs):  # a planned sweep builds its runs as they are read
        order.append(run.info.run_id)
        found = None if overwrite else reusable(out_dir, run)
        if found is not None:
            by_id[run.info.run_id] = found
        else:
            path = log_path(out_dir, run)
            if partials and any(n.startswith(f"{path.name}.") for n in partials):
                remove_stale_partials(path)
            todo.append(index)
            work += run.work
    check_space(work, out_dir, allow_large=allow_large)
    pending = Subset(runs, todo)
    tracker = Tracker("record", len(todo), progress, reused=len(by_id))
    if by_id:
        tracker.say(f"reused {len(by_id)} complete log(s) in {out_dir}/, running {len(todo)}")
    workers = min(threads or available_cpus(), len(todo))
    if executor is None or executor.name == "local":
        forked = workers > 1 and can_fork()
        executor = (
            ProcessExecutor(workers, min_items=2, start="fork") if forked else LocalExecutor()
        )
    ranges = task_ranges(len(pending), executor.slots)
    groups: list[Sequence[PlannedRun]]
    if isinstance(executor, ProcessExecutor) and executor.start == "fork":
        groups = [Subset(pending, r) for r in ranges]  # read in the workers
    else:
        groups = [[portable(pending[i]) for i in r] for r in ranges]
    task = functools.partial(  # absolute: a worker's working folder is not the driver's
        record_logs, out_dir=out_dir.absolute(), reuse=not overwrite
    )
    written = 0  # logs of this job complete so far
    for outcome in executor.map(task, groups) if groups else ():
        full = outcome.exception
        if isinstance(full, LogWriteError):  # with the logs its task wrote before
            raise LogWriteError(full.path, full.problem, written + full.written)
        if outcome.ok:
            done = [dataclasses.replace(s, path=out_dir / s.path.name) for s in outcome.value or []]
        else:
            reason = outcome.error or "task failed"
            done = [_lost(out_dir, run, reason, overwrite) for run in groups[outcome.index]]
        for result in done:
            by_id[result.run_id] = result
            written += result.status == "recorded"
            _count(tracker, result)
    return RecordResult([by_id[run_id] for run_id in order if run_id in by_id])


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

    Several tasks per slot keep every slot busy until the end, and a task stays
    small enough that a retry costs little and results stream to the driver.
    """
    size = max(1, min(max_runs, math.ceil(runs / (max(1, slots) * TASKS_PER_SLOT))))
    return [range(i, min(i + size, runs)) for i in range(0, runs, size)]


def _lost(out_dir: Path, run: PlannedRun, reason: str, overwrite: bool) -> RecordedRun:
    """A run of a task that failed (its worker killed): recorded when its log is complete,
    else failed (what a dead worker was writing removed)."""
    remove_stale_partials(log_path(out_dir, run))
    found = None if overwrite else reusable(out_dir, run)
    if found is not None:
        return dataclasses.replace(found, status="recorded")
    return RecordedRun(run.info.run_id, log_path(out_dir, run), "failed", reason=reason)


def _count(tracker: Tracker, run: RecordedRun) -> None:
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
