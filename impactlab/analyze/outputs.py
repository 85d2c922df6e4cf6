"""Writing the analysis tables: Parquet files and `summary.json` (all table file output)."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path
from typing import Any

import polars as pl

from impactlab.errors import ImpactlabError

ENERGY_ROWS_PER_RUN = 4000
"""The energy table keeps at most about this many rows per body and run (every k-th step)."""


class OutputError(ImpactlabError):
    """The output folder cannot be created or written."""

    exit_code = 2

    def __init__(self, path: Path, problem: str) -> None:
        super().__init__(f"{path}: {problem}")


def check_writable(out_dir: Path) -> None:
    """Create the output folder and prove a file can be written in it.

    Raises:
        OutputError: it cannot (exit code 2).
    """
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "figures").mkdir(exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out_dir, prefix=".impactlab-write-test-"):
            pass
    except OSError as exc:
        raise OutputError(out_dir, f"cannot write there: {exc.strerror or exc}") from None


def decimate(energy: pl.DataFrame, *, max_rows: int = ENERGY_ROWS_PER_RUN) -> pl.DataFrame:
    """Every k-th row per (run, body), k = ceil(rows / max_rows) of that run; last row kept."""
    if energy.is_empty():
        return energy
    group = ("run_id", "body")
    idx = pl.int_range(pl.len()).over(group)
    n = pl.len().over(group)
    k = ((n + max_rows - 1) // max_rows).clip(1)
    return energy.filter((idx % k == 0) | (idx == n - 1))


def write_parquet(frame: pl.DataFrame, path: Path) -> Path:
    """Write one table (zstd) and return its path."""
    frame.write_parquet(path, compression="zstd")
    return path


def _clean(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_clean(v) for v in value]
    return value


def write_summary(summary: dict[str, Any], path: Path) -> Path:
    """Write `summary.json` (NaN and inf as null)."""
    path.write_text(json.dumps(_clean(summary), indent=2, default=str) + "\n")
    return path
