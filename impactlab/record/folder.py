"""The record job's output folder: where each run's log goes, and which logs can be reused."""

from __future__ import annotations

from pathlib import Path

import mujoco

from impactlab.logs import format as logformat
from impactlab.logs.status import complete_metadata
from impactlab.record.planner import PlannedRun
from impactlab.record.results import RecordedRun


def log_path(out_dir: Path, run: PlannedRun) -> Path:
    """Where a run's log goes: named by experiment, sweep point and spec hash."""
    return out_dir / f"{run.info.run_id}.mcap"


def reusable(out_dir: Path, run: PlannedRun) -> RecordedRun | None:
    """The run's complete log in `out_dir` as a reused run, or None when it must be recorded.

    A log is reused when it is finished and was made from the same spec (hash) by the same
    MuJoCo and log format version.
    """
    path = log_path(out_dir, run)
    meta = complete_metadata(path)
    if meta is None:
        return None
    header = meta[logformat.RUN_METADATA]
    same = (
        header.get("spec_hash") == run.info.spec_hash
        and header.get("mujoco_version") == mujoco.__version__
        and header.get("log_format_version") == logformat.LOG_FORMAT_VERSION
    )
    if not same:
        return None
    return RecordedRun.reused(run.info.run_id, path, meta[logformat.OUTCOME_METADATA])
