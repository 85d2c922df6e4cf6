"""Replays in a notebook: the recordings written (`Recordings`), or one shown inline."""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from impactlab.errors import ImpactlabError, LogError
from impactlab.files import write_bytes
from impactlab.logs.load import load_log
from impactlab.progress import Progress, Tracker
from impactlab.replay.events import load_analysis
from impactlab.replay.recordings import recording
from impactlab.show import count, html_table, plain, where

NOTEBOOK_EXTRA = "pip install 'impactlab[notebook]'"


class Recordings(list[Path]):
    """The .rrd files a replay wrote: a list of paths that shows itself briefly."""

    def __repr__(self) -> str:
        folders = {p.parent for p in self}
        folder = f", {where(next(iter(folders)))}" if len(folders) == 1 else ""
        return f"<Recordings {count(len(self), '.rrd file')}, {_mb(self):.2f} MB{folder}>"

    def _repr_html_(self) -> str:
        rows = [[p.name, _mb([p])] for p in self[:30]]
        caption = repr(self).strip("<>")
        return html_table(["recording", "MB"], rows, caption=caption, total=len(self))


def _mb(paths: Sequence[Path]) -> float:
    return sum(p.stat().st_size for p in paths if p.is_file()) / 1e6


@dataclass(frozen=True)
class NotebookReplay:
    """One recording of runs, in memory, shown inline by a notebook (`display(replay)` or
    the cell's last value).

    Attributes:
        run_ids: the runs it holds.
        data: the recording as an .rrd stream (what `save` writes).
        width, height: the viewer's size in the cell (pixels; width "auto": the cell's).
    """

    run_ids: tuple[str, ...]
    data: bytes
    width: int | str = "auto"
    height: int = 480

    def __repr__(self) -> str:
        ids = ", ".join(plain(r) for r in self.run_ids[:3])
        more = f", … {len(self.run_ids) - 3} more" if len(self.run_ids) > 3 else ""
        size = len(self.data) / 1e6
        return f"<NotebookReplay {count(len(self.run_ids), 'run')}, {size:.2f} MB: {ids}{more}>"

    def viewer(self) -> Any:
        """A new Rerun viewer widget (`rerun_notebook.Viewer`) with the recording queued:
        it shows it once the notebook has displayed it.

        Raises:
            ImpactlabError: rerun-notebook is not installed.
        """
        require_notebook()
        from rerun_notebook import Viewer

        viewer = Viewer(width=self.width, height=self.height)
        viewer.send_rrd(self.data)
        return viewer

    def save(self, path: str | Path) -> Path:
        """Write the recording to an .rrd file (atomically), to open with `rerun FILE`."""
        return write_bytes(Path(path), self.data)

    def _ipython_display_(self) -> None:
        from IPython.display import display

        display(self.viewer())  # type: ignore[no-untyped-call]  # IPython: no hints


def require_notebook() -> None:
    """Raises ImpactlabError when rerun-notebook (the `notebook` extra) is missing."""
    if importlib.util.find_spec("rerun_notebook") is None:
        raise ImpactlabError(f"an inline replay needs rerun-notebook: {NOTEBOOK_EXTRA}")


def notebook_replay(
    logs: Sequence[Path],
    *,
    analysis_dir: Path | None = None,
    progress: Progress | None = None,
) -> NotebookReplay:
    """One in-memory recording of every readable log (as `impactlab replay -o ONE.rrd`).

    Raises:
        ImpactlabError: rerun-notebook is not installed.
        LogError: no log can be read, or the analysis folder cannot.
    """
    require_notebook()
    tables = load_analysis(analysis_dir) if analysis_dir is not None else None
    tracker = Tracker("replay", len(logs), progress)
    runs = []
    for path in logs:
        try:
            run = load_log(path)
        except ImpactlabError as exc:
            tracker.say(f"impactlab: error: {exc}", "error")
            tracker.add("failed")
            continue
        for problem in run.problems:
            tracker.say(f"impactlab: warning: {path}: {problem}", "warning")
        runs.append(run)
        tracker.add("finished")
    if not runs:
        raise LogError(" ".join(map(str, logs)), "no readable log to replay")
    return NotebookReplay(tuple(run.run_id for run in runs), recording(runs, tables))
