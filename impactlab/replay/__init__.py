"""Replay: logs (and their analysis) -> Rerun recordings, and the function `replay`."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Literal, overload

if TYPE_CHECKING:
    from impactlab.progress import Progress
    from impactlab.replay.notebook import NotebookReplay


@overload
def replay(
    logs: str | Path | Sequence[str | Path],
    *,
    out: str | Path | None = None,
    analysis: str | Path | None = None,
    progress: Progress | None = None,
    verbose: bool = False,
    notebook: Literal[False] = False,
) -> list[Path]: ...


@overload
def replay(
    logs: str | Path | Sequence[str | Path],
    *,
    out: None = None,
    analysis: str | Path | None = None,
    progress: Progress | None = None,
    verbose: bool = False,
    notebook: Literal[True],
) -> NotebookReplay: ...


def replay(
    logs: str | Path | Sequence[str | Path],
    *,
    out: str | Path | None = None,
    analysis: str | Path | None = None,
    progress: Progress | None = None,
    verbose: bool = False,
    notebook: bool = False,
) -> list[Path] | NotebookReplay:
    """Write Rerun recordings of logs; returns the .rrd files written (a list, `Recordings`).

    Args:
        logs: log files, folders or glob patterns.
        out: None: `<log>.rrd` next to each log; a path ending in `.rrd`: one recording of
            all runs; otherwise a folder for one `<log stem>.rrd` per log.
        analysis: an analysis output folder, whose tables give the event texts.
        progress: called with each `impactlab.progress.ProgressEvent`; None: silent.
        verbose: report progress on the console (when `progress` is None).
        notebook: write nothing; return one recording of all runs, in memory, that a
            notebook shows inline (`impactlab.replay.notebook.NotebookReplay`; needs
            `pip install 'impactlab[notebook]'`).

    Raises:
        NoLogs: no input names a log (a folder without logs, a pattern matching nothing).
        OutputError: `out` cannot be written (e.g. it is a file that is not `.rrd`).
        LogError: the analysis folder cannot be read.
        ImpactlabError: `notebook` without rerun-notebook installed.
        ValueError: `notebook` with `out` (an inline replay writes no file: `.save(path)`).
    """
    from impactlab.logs.inputs import require_logs
    from impactlab.progress import reporter, say
    from impactlab.replay.notebook import Recordings, notebook_replay
    from impactlab.replay.recordings import replay_logs

    if notebook and out is not None:
        raise ValueError("an inline replay writes no file: call .save(path) on it instead of out=")
    inputs = [logs] if isinstance(logs, str | Path) else list(logs)
    paths, empty = require_logs(inputs)
    with reporter(progress, verbose) as shown:
        for where, why in empty:
            say(shown, "replay", f"impactlab: error: {where}: {why}", "error")
        analysis_dir = None if analysis is None else Path(analysis)
        if notebook:
            return notebook_replay(paths, analysis_dir=analysis_dir, progress=shown)
        written = replay_logs(
            paths,
            out=None if out is None else Path(out),
            analysis_dir=analysis_dir,
            progress=shown,
        )
        return Recordings(written)
