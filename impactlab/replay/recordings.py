"""Logs (and their analysis) -> Rerun recordings, written atomically or streamed to a viewer."""

from __future__ import annotations

import errno
import hashlib
import json
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import polars as pl
import rerun as rr
import rerun.blueprint as rrb

from impactlab.errors import ImpactlabError, LogError
from impactlab.files import FULL, OutputError, check_writable, write_bytes
from impactlab.logs.labels import run_labels as labels_of
from impactlab.logs.load import RunLog, load_log
from impactlab.progress import Progress, Tracker
from impactlab.replay import style
from impactlab.replay.blueprint import replay_blueprint
from impactlab.replay.convert import log_run
from impactlab.replay.events import events_for, load_analysis

if TYPE_CHECKING:
    import polars as pl

APPLICATION_ID = "impactlab"


def replay_logs(
    logs: Sequence[Path],
    *,
    out: Path | None,
    analysis_dir: Path | None,
    viewer_sinks: Sequence[Callable[[], rr.GrpcSink]] = (),
    on_error: Callable[[ImpactlabError], None] | None = None,
    progress: Progress | None = None,
) -> list[Path]:
    """Convert logs into .rrd recordings; returns the files written.

    Args:
        logs: MCAP logs.
        out: None: `<log>.rrd` next to each log; a path ending in `.rrd`: one recording of
            all runs (one `/runs/<run_id>` subtree each); otherwise a folder for
            `<log stem>.rrd` files (created).
        analysis_dir: analysis output folder whose `bounces.parquet` / `collisions.parquet`
            rows give the events (the log's contacts otherwise).
        viewer_sinks: factories of extra sinks (e.g. `rr.GrpcSink`) each recording also goes to.
        on_error: called with the error of each log that cannot be read or written; the
            others are converted all the same.
        progress: receives one count per recording, and a line per error and per damaged
            or incomplete log; None: silent.

    Raises:
        LogError: the analysis folder is missing or holds an unreadable table.
        OutputError: `out` cannot be written: a file that is not `.rrd`, a folder that
            cannot be created or written (checked before any conversion), a full disk.
    """
    tables = load_analysis(analysis_dir) if analysis_dir is not None else None
    if out is not None and out.suffix.lower() == ".rrd" and not out.is_dir():
        check_writable(out.parent)
        groups = [(out, list(logs))]
    else:
        if out is not None and out.exists() and not out.is_dir():
            raise OutputError(out, "is a file, not a folder (give FILE.rrd for one recording)")
        if out is not None:
            check_writable(out)
        folder = out
        groups = [((folder or log.parent) / f"{log.stem}.rrd", [log]) for log in logs]
    tracker = Tracker("replay", len(groups), progress)

    def error(exc: ImpactlabError) -> None:
        tracker.say(f"impactlab: error: {exc}", "error")
        if on_error is not None:
            on_error(exc)

    written = []
    sinks = list(viewer_sinks)
    for target, group in groups:
        runs = []
        for log in group:
            try:
                run = load_log(log)
            except ImpactlabError as exc:
                error(exc)
                continue
            for problem in run.problems:
                tracker.say(f"impactlab: warning: {log}: {problem}", "warning")
            runs.append(run)
        if not runs:
            tracker.add("failed")
            continue
        try:
            written.append(write_recording(runs, target, tables=tables))
        except OSError as exc:
            if exc.errno in FULL:  # nothing more can be written
                raise OutputError(target, f"cannot write: {exc.strerror}") from None
            error(LogError(str(target), f"cannot write: {exc.strerror or exc}"))
        for make in sinks:
            try:
                recording(runs, tables, sink=make())
            except RuntimeError as exc:  # the SDK's error when no viewer answers
                error(ImpactlabError(f"viewer: {exc}"))
                sinks = []  # one error is enough; the files are still written
        tracker.add("finished")
    return written


def write_recording(
    runs: Sequence[RunLog], path: Path, *, tables: Mapping[str, pl.DataFrame] | None = None
) -> Path:
    """Write one recording of `runs` to `path` atomically, with the replay blueprint as default.

    The recording is made in memory (as large as the runs' data, which is in memory already)
    and written as any file is: a full disk is the system's error, nothing half-written.

    Raises:
        OSError: the file cannot be written.
    """
    data = recording(runs, tables)
    if not data:
        raise OSError(errno.EIO, "the recording was not made")
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_bytes(path, data)


def recording(
    runs: Sequence[RunLog],
    tables: Mapping[str, pl.DataFrame] | None,
    *,
    sink: rr.GrpcSink | None = None,
) -> bytes:
    """The recording of `runs` (its id: the run's, or a digest of theirs) as an .rrd stream
    made in memory, or sent to a viewer's `sink` (then b"").

    Raises:
        RuntimeError: the viewer cannot be reached.
    """
    ids = [run.run_id for run in runs]
    recording_id = ids[0] if len(ids) == 1 else "replay-" + _digest(ids)
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id, send_properties=False)
    stream = rr.binary_stream(recording=rec) if sink is None else None
    try:
        if sink is not None:
            rec.set_sinks(sink)
        log_runs(rec, runs, tables, active=sink is None)
        return b"" if stream is None else bytes(stream.read(flush=True) or b"")
    finally:
        rec.disconnect()


def log_runs(
    rec: rr.RecordingStream,
    runs: Sequence[RunLog],
    tables: Mapping[str, pl.DataFrame] | None,
    *,
    active: bool = False,
) -> rrb.Blueprint:
    """Every run, the recording's name and the blueprint (returned); flushed.

    The blueprint is the default, and with `active` (files, the notebook's recording) also
    the active one: the web viewer shows only an active blueprint; a viewer streamed to
    keeps the layout it has.
    """
    ids = [run.run_id for run in runs]
    rec.send_recording_name(ids[0] if len(ids) == 1 else f"{len(ids)} runs")
    labels = run_labels(runs)
    colors = style.PALETTE if len(runs) > 1 else [None]
    logged = [
        log_run(rec, run, events_for(run, tables), label=label, color=colors[i % len(colors)])
        for i, (run, label) in enumerate(zip(runs, labels, strict=True))
    ]
    blueprint = replay_blueprint(logged)
    rec.send_blueprint(blueprint, make_active=active, make_default=True)
    rec.flush()
    return blueprint


def run_labels(runs: Sequence[RunLog]) -> list[str]:
    """What tells runs apart in one recording (their series' names begin with it): none for
    one run, else the report's label of each run (`logs.labels.run_labels`)."""
    if len(runs) < 2:
        return [""]
    frame = pl.DataFrame(
        {
            "run_id": [r.run_id for r in runs],
            "experiment": [r.experiment for r in runs],
            "sweep": [json.dumps(r.sweep) for r in runs],
        }
    )
    labels = dict(labels_of(frame).iter_rows())
    return [labels[r.run_id] for r in runs]


def _digest(ids: Sequence[str]) -> str:
    return hashlib.sha256("\n".join(ids).encode()).hexdigest()[:12]
