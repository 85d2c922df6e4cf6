"""The energy table as written: decimated to a bounded number of rows per run."""

from __future__ import annotations

import polars as pl

ENERGY_ROWS_PER_RUN = 4000
"""The energy table keeps at most about this many rows per body and run (every k-th step)."""


def decimate(energy: pl.DataFrame, *, max_rows: int = ENERGY_ROWS_PER_RUN) -> pl.DataFrame:
    """Every k-th row per (run, body), k = ceil(rows / max_rows) of that run; last row kept."""
    if energy.is_empty():
        return energy
    group = ("run_id", "body")
    idx = pl.int_range(pl.len()).over(group)
    n = pl.len().over(group)
    k = ((n + max_rows - 1) // max_rows).clip(1)
    return energy.filter((idx % k == 0) | (idx == n - 1))
