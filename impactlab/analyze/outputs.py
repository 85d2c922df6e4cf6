"""The energy table as written: decimated to a bounded number of rows per run."""

from __future__ import annotations

import dataclasses

import polars as pl

from impactlab.analyze.analysis import RunAnalysis

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


def with_decimated_energy(a: RunAnalysis) -> RunAnalysis:
    """The analysis with its energy frame decimated as it is written (`decimate`), and the
    full-resolution counts in `energy_logged`; unchanged when that was done already."""
    if a.energy_logged != (0, 0) or not a.energy.height:
        return a
    longest = int(a.energy.group_by("body").len()["len"].max())
    energy = a.energy if longest <= ENERGY_ROWS_PER_RUN else decimate(a.energy)  # k = 1: as is
    return dataclasses.replace(a, energy=energy, energy_logged=(a.energy.height, longest))
