"""Record a list of planned runs, one after the other: each run's rows streamed into its log."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from impactlab.errors import ImpactlabError
from impactlab.executors.base import describe_error
from impactlab.files import FULL
from impactlab.logs.checks import step_ns
from impactlab.logs.writer import LogWriter
from impactlab.record.folder import log_path, reusable
from impactlab.record.log_rows import impacts, log_header, log_rows, outcome
from impactlab.record.model import InstrumentedModel
from impactlab.record.planner import PlannedRun
from impactlab.record.results import RecordedRun
from impactlab.record.simulate import Piece, RunRequest, simulate


class LogWriteError(ImpactlabError):
    """A log cannot be written (a full disk): nothing more of the job can be."""

    def __init__(self, path: Path, problem: str, written: int) -> None:
        self.path, self.problem, self.written = path, problem, written
        super().__init__(
            f"{path}: cannot write the log: {problem} "
            f"({written} log(s) of this job written before it are complete)"
        )

    def __reduce__(self) -> tuple[type[LogWriteError], tuple[Path, str, int]]:
        return LogWriteError, (self.path, self.problem, self.written)  # from a worker


def requests(
    runs: Sequence[PlannedRun],
    out_dir: Path,
    *,
    reuse: bool,
    report: Callable[[RecordedRun], None],
) -> Iterator[RunRequest]:
    """Each run built when the simulation reaches it. With `reuse`, a run whose complete log
    is in `out_dir` (e.g. written by a concurrent job meanwhile) is `report`ed instead, as is
    one whose model fails to build (failed)."""
    for run in runs:
        found = reusable(out_dir, run) if reuse else None
        if found is not None:
            report(found)
            continue
        try:
            inst = run.build()
        except Exception as exc:  # e.g. a model that no longer compiles on a worker
            reason = str(exc) if isinstance(exc, ImpactlabError) else describe_error(exc)
            report(_failed(run, log_path(out_dir, run), reason))
            continue
        yield RunRequest(inst, run.max_time, run.stop, run.info.log_every, tag=run)


def _failed(run: PlannedRun, path: Path, reason: str) -> RecordedRun:
    return RecordedRun(run.info.run_id, path, "failed", reason=reason)


class _OpenLog:
    """One run's log being written as its pieces arrive."""

    def __init__(self, run: PlannedRun, inst: InstrumentedModel, path: Path) -> None:
        self.run, self.inst, self.path = run, inst, path
        self.writer = LogWriter(path, log_header(inst, run.info))

    def add(self, piece: Piece) -> RecordedRun | None:
        """Write a piece's rows; on the run's last piece, finish the log and say so."""
        if piece.t_ns.size:
            assert piece.contacts is not None  # every piece with rows has their contacts
            rows = log_rows(self.inst, piece.t_ns, piece.sensordata, piece.work, piece.contacts)
            self.writer.write(rows)
        if piece.ending is None:
            return None
        end = piece.ending
        dt_ns = step_ns(float(self.inst.model.opt.timestep))
        self.writer.finish(outcome(end), impacts(self.inst, end, dt_ns))
        v = end.verdict
        return RecordedRun(
            self.run.info.run_id,
            self.path,
            "recorded",
            v.outcome,
            v.reason,
            tuple(end.warnings),
            end.t_end_ns / 1e9,
            end.steps,
            end.logged,
            piece.wall_s,
        )

    def abort(self) -> None:
        self.writer.abort()


def record_logs(
    runs: Sequence[PlannedRun],
    out_dir: Path,
    *,
    reuse: bool = True,
) -> list[RecordedRun]:
    """Simulate and write every run (the body of one record task); returns one `RecordedRun`
    per run, in order of completion.

    A run that fails to build or simulate fails alone. A log that cannot be written for a full
    disk (`files.FULL`: nothing more can be written) raises `LogWriteError`
    saying how many logs of these runs are complete; for another reason (a folder in its
    place) it fails its run.
    With `reuse`, a run whose complete log is there already (a retried task, a concurrent
    job) is not simulated again: the folder is looked at just before the run would be. On
    any exit (an error, Ctrl-C) the logs being written are removed.
    """
    out: list[RecordedRun] = []
    report = out.append

    logs: dict[RunRequest, _OpenLog] = {}
    dead: set[RunRequest] = set()  # runs whose log failed: their further rows are dropped
    try:
        built = requests(runs, out_dir, reuse=reuse, report=report)
        with contextlib.closing(simulate(built)) as pieces:
            for piece in pieces:
                request, run = piece.request, piece.request.tag
                path = log_path(out_dir, run)
                if piece.error is not None:
                    if request in logs:
                        logs.pop(request).abort()
                    report(_failed(run, path, piece.error))
                    continue
                if request in dead:
                    continue
                try:
                    if request not in logs:
                        logs[request] = _OpenLog(run, request.inst, path)
                    done = logs[request].add(piece)
                except Exception as exc:
                    if request in logs:
                        logs.pop(request).abort()
                    if isinstance(exc, OSError) and exc.errno in FULL:  # nothing more fits
                        written = sum(r.status == "recorded" for r in out)
                        raise LogWriteError(path, exc.strerror or str(exc), written) from None
                    dead.add(request)
                    report(_failed(run, path, f"cannot write the log: {describe_error(exc)}"))
                    continue
                if done is not None:
                    del logs[request]
                    report(done)
    finally:
        for log in logs.values():
            log.abort()
    return out
