"""The energy table as written: decimated to a bounded number of rows per run."""

from __future__ import annotations

import dataclasses

import numpy as np
import polars as pl

from impactlab.analyze.measure.analysis import RunAnalysis

ENERGY_ROWS_PER_RUN = 4000
"""The energy table keeps at most about this many rows per body and run (every k-th step)."""


def decimate(energy: pl.DataFrame, *, max_rows: int | None = None) -> pl.DataFrame:
    """Every k-th row per (run, body), k = ceil(rows / max_rows) of that run; last row kept
    (max_rows: ENERGY_ROWS_PER_RUN by default)."""
    max_rows = ENERGY_ROWS_PER_RUN if max_rows is None else max_rows
    group = ("run_id", "body", "is_total")
    if energy.is_empty():
        return energy
    idx = pl.int_range(pl.len()).over(group)
    n = pl.len().over(group)
    k = ((n + max_rows - 1) // max_rows).clip(1)
    return energy.filter((idx % k == 0) | (idx == n - 1))


def with_decimated_energy(a: RunAnalysis) -> RunAnalysis:
    """The analysis with its energy frame decimated as it is written (`decimate`), and the
    full-resolution counts in `energy_logged`; unchanged when that was done already.

    An analysis' energy frame holds each body's rows together (by body, then time): the
    rows kept are then found in numpy from the blocks' lengths, with one filter.
    """
    if a.energy_logged != (0, 0) or not a.energy.height:
        return a
    # each row's body, null on the rows of the run's sum (a body may be named "total")
    body = a.energy.select(pl.when(pl.col("is_total")).then(None).otherwise(pl.col("body")))
    blocks = body.to_series().rle()
    lengths = blocks.struct.field("len").to_numpy().astype(np.int64)
    if len(set(blocks.struct.field("value").to_list())) != lengths.size:  # not by body
        longest = int(a.energy.group_by("body", "is_total").len()["len"].to_numpy().max())
        energy = a.energy if longest <= ENERGY_ROWS_PER_RUN else decimate(a.energy)
        return dataclasses.replace(a, energy=energy, energy_logged=(a.energy.height, longest))
    longest = int(lengths.max())
    energy = a.energy
    if longest > ENERGY_ROWS_PER_RUN:
        k = np.maximum((lengths + ENERGY_ROWS_PER_RUN - 1) // ENERGY_ROWS_PER_RUN, 1)
        at = np.arange(a.energy.height) - np.repeat(np.cumsum(lengths) - lengths, lengths)
        keep = (at % np.repeat(k, lengths) == 0) | (at == np.repeat(lengths, lengths) - 1)
        energy = a.energy.filter(pl.Series(keep))
    return dataclasses.replace(a, energy=energy, energy_logged=(a.energy.height, longest))
