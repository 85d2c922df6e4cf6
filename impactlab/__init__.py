"""impactlab: simulated impact experiments; the Python API (docs/python-api.md)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

# each stage package's face imports nothing heavy; bound after it, the name is the function
from impactlab.analyze import analyze
from impactlab.record import plan, record
from impactlab.replay import replay
from impactlab.version import __version__

if TYPE_CHECKING:
    from impactlab.logs.load import RunLog
    from impactlab.tools.diff import LogDiff

__all__ = ["__version__", "analyze", "diff", "load", "plan", "record", "replay"]


def load(path: str | Path) -> RunLog:
    """One log decoded into polars frames (`impactlab.logs.load.RunLog`).

    `bodies` (a frame per body), `contacts`, `energy`, `events`, `meta` (the run and
    outcome metadata), `partial` and `problems` (what is damaged or missing).

    Raises:
        LogError: the file is missing, not MCAP, or not an impactlab log.
    """
    from impactlab.logs.load import load_log

    return load_log(path)


def diff(
    a: str | Path | RunLog,
    b: str | Path | RunLog,
    *,
    atol: float | None = None,
    rtol: float | None = None,
) -> LogDiff:
    """Compare two logs (paths or loaded logs) channel by channel and field by field.

    Returns an `impactlab.tools.diff.LogDiff` (`.equal`, `.report()`, `.to_dict()`).
    """
    from impactlab.logs.load import RunLog, load_log
    from impactlab.tools import DEFAULT_ATOL, DEFAULT_RTOL
    from impactlab.tools.diff import Tolerance, diff_logs

    la, lb = (log if isinstance(log, RunLog) else load_log(log) for log in (a, b))
    atol, rtol = (DEFAULT_ATOL if atol is None else atol), (DEFAULT_RTOL if rtol is None else rtol)
    return diff_logs(la, lb, tolerance=Tolerance(atol=atol, rtol=rtol))
