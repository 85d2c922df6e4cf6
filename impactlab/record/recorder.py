"""The record job: reuse complete logs, record the rest here or on an executor, report."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from impactlab.executors.base import Executor, LocalExecutor
from impactlab.executors.processes import ProcessExecutor, available_cpus, can_fork
from impactlab.files import check_writable
from impactlab.logs.writer import PARTIAL_SUFFIX, remove_stale_partials
from impactlab.progress import Progress, Tracker
from impactlab.record.batch import BATCH_RUNS
from impactlab.record.folder import log_path, reusable
from impactlab.record.planner import PlannedRun, Subset
from impactlab.record.results import RecordedRun, RecordResult
from impactlab.record.tasks import record_on
from impactlab.record.work import Work, check_space


def record_runs(
    runs: Sequence[PlannedRun],
    out_dir: Path,
    *,
    executor: Executor | None = None,
    overwrite: bool = False,
    allow_large: bool = False,
    threads: int | None = None,
    batch_size: int = BATCH_RUNS,
    progress: Progress | None = None,
) -> RecordResult:
    """Record planned runs into `out_dir`, one log per run; reuse complete logs.

    Args:
        runs: from `impactlab.record.planner.plan`.
        out_dir: the output folder (created); on a cluster, a path every machine sees.
        executor: where the runs are simulated (default: here, on every core: the runs are
            shared among worker processes forked for the job (`ProcessExecutor`), one per
            core, each simulating batched rollouts while it writes their logs; where forking
            is not safe, in this process).
        overwrite: record again runs whose complete log exists.
        allow_large: record even when the logs to write are estimated larger than the
            free space in `out_dir`.
        threads: worker processes to fork here (default: one per available core; 1: this
            process only).
        batch_size: runs per rollout here.
        progress: receives the job's progress (see `impactlab.progress`); None: silent.

    Returns:
        Every run, in plan order, reused ones included.

    Raises:
        OutputError: the folder cannot be written (before any simulation).
        WorkError: the logs to write would not fit in the folder's free space.
        ImpactlabError: here, a log cannot be written (a full disk); the logs written before
            are complete.
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
    done = record_on(
        executor,
        pending,
        out_dir,
        tracker,
        overwrite=overwrite,
        batch_size=batch_size,
    )
    by_id |= {r.run_id: r for r in done}
    del done
    return RecordResult([by_id[run_id] for run_id in order if run_id in by_id])
