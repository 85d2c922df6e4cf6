"""Record a list of planned runs: batched rollouts, each run's log written as its batch ends.

Runs that share MuJoCo's size signature and timestep are simulated side by side in one
multi-threaded rollout (`batches`); while one batch's logs are written, the next batch
simulates (MuJoCo releases the GIL).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from impactlab.errors import ImpactlabError
from impactlab.executors.base import describe_error
from impactlab.record.folder import log_path
from impactlab.record.job import PlannedRun
from impactlab.record.log_rows import write_run_log
from impactlab.record.model import InstrumentedModel
from impactlab.record.results import RecordedRun
from impactlab.record.simulate import RunRequest, Trajectory, simulate_batch

BATCH_RUNS = 4  # runs simulated side by side: enough for two threads, few runs in memory

Built = list[tuple[PlannedRun, InstrumentedModel]]


def batches(runs: Sequence[PlannedRun], size: int) -> list[Built]:
    """Consecutive runs that can share a rollout (same MuJoCo sizes and timestep), built."""
    out: list[Built] = []
    key = None
    for run in runs:
        inst = run.build()
        m = inst.model
        this = (m.nq, m.nv, m.na, m.nu, m.nbody, m.ngeom, m.nsensordata, m.opt.timestep)
        if not out or this != key or len(out[-1]) >= size:
            out.append([])
            key = this
        out[-1].append((run, inst))
    return out


def record_batches(
    runs: Sequence[PlannedRun],
    out_dir: Path,
    *,
    batch_size: int = BATCH_RUNS,
    threads: int | None = None,
    stop_on_write_error: bool = True,
    on_run: Callable[[RecordedRun], None] = lambda _: None,
) -> list[RecordedRun]:
    """Simulate and write every run; returns one `RecordedRun` per run, in order of completion.

    A batch that fails to build or simulate fails only its own runs. A log that cannot be
    written fails its run, or, with `stop_on_write_error` (a full disk: nothing more can be
    written), raises `ImpactlabError` saying how many logs of the job are complete.
    `on_run` is called with each run as soon as its log is written.
    """
    out: list[RecordedRun] = []

    def failed(run: PlannedRun, reason: str) -> RecordedRun:
        return RecordedRun(run.info.run_id, log_path(out_dir, run), "failed", reason=reason)

    try:
        groups = batches(runs, batch_size)
    except Exception as exc:  # e.g. a model that no longer compiles on a worker
        reason = describe_error(exc)
        for run in runs:
            out.append(failed(run, reason))
            on_run(out[-1])
        return out

    def simulate(batch: Built) -> tuple[list[Trajectory] | str, float]:
        start = time.perf_counter()
        requests = [
            RunRequest(inst, run.max_time, run.stop, run.info.log_every) for run, inst in batch
        ]
        try:
            result: list[Trajectory] | str = simulate_batch(requests, threads=threads)
        except Exception as exc:
            result = describe_error(exc)
        return result, time.perf_counter() - start

    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="impactlab-sim") as pool:
        pending = pool.submit(simulate, groups[0]) if groups else None
        for i, batch in enumerate(groups):
            assert pending is not None
            trajectories, seconds = pending.result()
            if i + 1 < len(groups):
                pending = pool.submit(simulate, groups[i + 1])
            if isinstance(trajectories, str):
                for run, _ in batch:
                    out.append(failed(run, trajectories))
                    on_run(out[-1])
                continue
            for (run, inst), traj in zip(batch, trajectories, strict=True):
                t0 = time.perf_counter()
                path = log_path(out_dir, run)
                try:
                    write_run_log(path, inst, run.info, traj)
                except Exception as exc:
                    if stop_on_write_error and isinstance(exc, OSError):
                        done = sum(r.status == "recorded" for r in out)
                        raise ImpactlabError(
                            f"{path}: cannot write the log: {exc.strerror or exc} "
                            f"({done} log(s) of this job written before it are complete)"
                        ) from None
                    out.append(failed(run, f"cannot write the log: {describe_error(exc)}"))
                else:
                    v = traj.verdict
                    out.append(
                        RecordedRun(
                            run.info.run_id,
                            path,
                            "recorded",
                            v.outcome,
                            v.reason,
                            tuple(traj.warnings),
                            traj.t_ns[-1] / 1e9 if traj.t_ns.size else 0.0,
                            v.last_step + 1,
                            int(traj.t_ns.size),
                            seconds / len(batch) + time.perf_counter() - t0,
                        )
                    )
                on_run(out[-1])
    return out
