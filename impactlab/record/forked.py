"""Record runs in forked worker processes, one per core, each simulating and writing its share."""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import traceback
from collections.abc import Sequence
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from impactlab.logs.writer import remove_partials_of
from impactlab.record.batch import LogWriteError, Report, Reuse, record_batches
from impactlab.record.folder import log_path
from impactlab.record.planner import PlannedRun, Subset
from impactlab.record.results import RecordedRun

DIED = "its worker process died (killed or out of memory)"
PR_SET_PDEATHSIG = 1  # prctl(2): the signal a process gets when its parent dies


def can_fork() -> bool:
    """Whether worker processes may be forked here: Linux, and no other Python thread."""
    return (
        sys.platform.startswith("linux")
        and "fork" in multiprocessing.get_all_start_methods()
        and threading.active_count() == 1
    )


def share_ranges(steps: Sequence[float], parts: int) -> list[range]:
    """Runs, given by their steps, cut into at most `parts` consecutive ranges of about equal
    work (consecutive runs are mostly points of one sweep: kept together they share rollouts)."""
    weights = [max(1.0, w) for w in steps]
    total = sum(weights)
    starts = [0]
    done = 0.0
    for index, weight in enumerate(weights):
        if index > starts[-1] and done >= total * len(starts) / parts and len(starts) < parts:
            starts.append(index)
        done += weight
    return [range(a, b) for a, b in zip(starts, [*starts[1:], len(weights)], strict=True)]


def record_forked(
    runs: Sequence[PlannedRun],
    out_dir: Path,
    *,
    workers: int,
    batch_size: int,
    reuse: Reuse | None = None,
    on_run: Report = lambda _: None,
    steps: Sequence[float] | None = None,
) -> list[RecordedRun]:
    """Record `runs` over `workers` forked processes; one `RecordedRun` per run, in order of
    completion. `on_run` is called here as each run's log is complete. `steps`: each run's
    steps, when known (else read from the runs), to share the work.

    The workers inherit `runs` (a sequence that may build its runs when read) and each
    reads only its share, as it records it.

    Raises:
        LogWriteError: a worker could not write a log (a full disk); the logs reported
            before are complete.
    """
    context = multiprocessing.get_context("fork")
    sys.stdout.flush()
    sys.stderr.flush()
    pending: dict[Connection, tuple[Any, Subset[PlannedRun]]] = {}
    processes = []
    out: list[RecordedRun] = []
    try:
        if steps is None:
            steps = [float(r.work.steps) for r in runs]
        for indices in share_ranges(steps, workers):
            share = Subset(runs, indices)
            receive, send = context.Pipe(duplex=False)
            process = context.Process(
                target=_work,
                args=(share, out_dir, batch_size, reuse, send, os.getpid()),
                name="impactlab-record",
                daemon=True,
            )
            process.start()
            send.close()
            processes.append(process)
            pending[receive] = (process, share)
        reported: set[str] = set()
        while pending:
            for conn in wait(list(pending)):
                assert isinstance(conn, Connection)  # wait() hands back what it was given
                process, share = pending[conn]
                try:
                    kind, value = conn.recv()
                except EOFError:  # the worker is gone without saying it is done
                    del pending[conn]
                    process.join()
                    remove_partials_of(out_dir, process.pid)  # dead and reaped
                    for run in share:
                        if run.info.run_id not in reported:
                            failed = RecordedRun(
                                run.info.run_id, log_path(out_dir, run), "failed", reason=DIED
                            )
                            out.append(failed)
                            on_run(failed)
                    continue
                if kind == "run":
                    reported.add(value.run_id)
                    out.append(value)
                    on_run(value)
                elif kind == "error":
                    written = sum(r.status == "recorded" for r in out)
                    path, problem = value
                    raise LogWriteError(path, problem, written)
                elif kind == "bug":
                    raise RuntimeError(f"a record worker failed:\n{value}")
                else:  # "done"
                    del pending[conn]
    finally:
        for process, _ in pending.values():
            if process.is_alive():
                process.terminate()  # it ends at once (`_end`)
        for process in processes:
            process.join()
        for process, _ in pending.values():  # what the stopped workers were writing
            remove_partials_of(out_dir, process.pid)
    return out


def _end(signum: int, frame: object) -> None:
    """SIGTERM or SIGINT in a worker: it ends at once (nothing it could print, no traceback);
    the caller removes what it was writing once it is reaped (or, if the caller was killed
    too, the next job does: `remove_stale_partials`)."""
    os._exit(1)


def _die_with(parent: int) -> None:
    """Have the kernel send this process SIGTERM when its parent dies (even by SIGKILL)."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    if os.getppid() != parent:  # it died before the request took effect
        os._exit(1)


def _work(
    runs: Sequence[PlannedRun],
    out_dir: Path,
    batch_size: int,
    reuse: Reuse | None,
    send: Any,
    parent: int,
) -> None:
    """A worker: record its share with one simulation thread, report each run."""
    signal.signal(signal.SIGTERM, _end)
    signal.signal(signal.SIGINT, _end)  # Ctrl-C reaches the workers too: the caller stops them
    try:
        try:
            _die_with(parent)
            record_batches(
                runs,
                out_dir,
                batch_size=batch_size,
                threads=1,
                reuse=reuse,
                on_run=lambda run: send.send(("run", run)),
                keep=False,
            )
            send.send(("done", None))
        except LogWriteError as exc:
            send.send(("error", (exc.path, exc.problem)))
        except Exception:  # a bug: its traceback goes to the caller
            send.send(("bug", traceback.format_exc()))
    except OSError:  # the caller is gone (a closed pipe): nobody to tell
        pass
