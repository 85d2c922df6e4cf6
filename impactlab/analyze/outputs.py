"""The energy table as written: decimated to a bounded number of rows per run."""

from __future__ import annotations

import dataclasses

import numpy as np
import polars as pl

from impactlab.analyze.analysis import RunAnalysis

ENERGY_ROWS_PER_RUN = 4000
"""The energy table keeps at most about this many rows per body and run (every k-th step)."""


def decimate(
    energy: pl.DataFrame,
    *,
    max_rows: int = ENERGY_ROWS_PER_RUN,
    group: tuple[str, ...] = ("run_id", "body"),
) -> pl.DataFrame:
    """Every k-th row per (run, body), k = ceil(rows / max_rows) of that run; last row kept.

    `group`: the columns that tell the runs' bodies apart (another key than run_id when
    one frame holds two runs of one id)."""
    if energy.is_empty():
        return energy
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
    energy = (
        a.energy
        if longest <= ENERGY_ROWS_PER_RUN
        else decimate(a.energy, max_rows=ENERGY_ROWS_PER_RUN)
    )
    return dataclasses.replace(a, energy=energy, energy_logged=(a.energy.height, longest))


def with_decimated_energies(analyses: list[RunAnalysis]) -> list[RunAnalysis]:
    """`with_decimated_energy` of each analysis, in a few operations for all of them."""
    todo = [i for i, a in enumerate(analyses) if a.energy_logged == (0, 0) and a.energy.height]
    if len(todo) < 2:
        return [with_decimated_energy(a) for a in analyses]
    key = "_analysis"
    every = pl.concat(
        [
            analyses[i].energy.hstack([pl.Series(key, np.full(analyses[i].energy.height, i))])
            for i in todo
        ]
    )
    counts = every.group_by(key, "body").len().group_by(key).agg(pl.col("len").max())
    longest = dict(zip(counts[key].to_list(), counts["len"].to_list(), strict=True))
    kept = {
        int(k[0]): f.drop(key)
        for k, f in decimate(every, max_rows=ENERGY_ROWS_PER_RUN, group=(key, "body"))
        .partition_by(key, as_dict=True, maintain_order=True)
        .items()
    }
    out = list(analyses)
    for i in todo:
        a = analyses[i]
        energy = a.energy if longest[i] <= ENERGY_ROWS_PER_RUN else kept[i]
        out[i] = dataclasses.replace(a, energy=energy, energy_logged=(a.energy.height, longest[i]))
    return out
