"""impactlab: simulated impact experiments (record to MCAP, analyze in polars, replay in Rerun).

The Python API (docs/python-api.md), each name imported on first use:

- `impactlab.record(spec_or_path, out=..., overrides=...)`: simulate, one MCAP log per run.
- `impactlab.plan(spec_or_path, overrides=...)`: the runs a spec gives, validated.
- `impactlab.load(path)`: one log as polars frames per channel, with its metadata.
- `impactlab.analyze(paths)`: the analysis tables as polars frames.
- `impactlab.replay(paths, out=...)`: Rerun recordings.
- `impactlab.diff(a, b)`: two logs compared field by field.

Nothing prints unless asked (`progress=` or `verbose=True`).

For a type checker (the package ships `py.typed`), `impactlab.record`, `impactlab.analyze`
and `impactlab.replay` are the functions (imported below under TYPE_CHECKING), also after
`import impactlab.analyze`; a stage's other names are imported from it
(`from impactlab.analyze import AnalysisResult`).
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import TYPE_CHECKING, Any

from impactlab.version import __version__

if TYPE_CHECKING:
    from impactlab.analyze import analyze as analyze
    from impactlab.logs.load import RunLog
    from impactlab.record import plan as plan
    from impactlab.record import record as record
    from impactlab.replay import replay as replay
    from impactlab.tools.diff import LogDiff

__all__ = ["__version__", "analyze", "diff", "load", "plan", "record", "replay"]

_STAGES = ("record", "analyze", "replay")  # callable packages

if not TYPE_CHECKING:  # a type checker sees the imports above, and no attribute it does not

    def __getattr__(name: str) -> Any:
        if name in _STAGES:
            return importlib.import_module(f"impactlab.{name}")
        if name == "plan":
            return importlib.import_module("impactlab.record").plan
        raise AttributeError(f"module 'impactlab' has no attribute {name!r}")


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
    from impactlab.tools import DEFAULT_ATOL, DEFAULT_IGNORED_META, DEFAULT_RTOL
    from impactlab.tools.diff import Tolerance, diff_logs

    la = a if isinstance(a, RunLog) else load_log(a)
    lb = b if isinstance(b, RunLog) else load_log(b)
    tolerance = Tolerance(
        atol=DEFAULT_ATOL if atol is None else atol, rtol=DEFAULT_RTOL if rtol is None else rtol
    )
    return diff_logs(la, lb, tolerance=tolerance, ignore_meta=DEFAULT_IGNORED_META)
