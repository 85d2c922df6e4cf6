"""Readable run labels: the experiment and its sweep point in words and units.

A run id carries a hash (`drop-ball.pos=0_0_3-c08cac40`); a reader wants "drop: ball released
at z = 3 m". The hash stays in the report's details table only.
"""

from __future__ import annotations

import polars as pl

from impactlab.analyze.tables.studies import study_parameters, with_parameters
from impactlab.logs.labels import parameter_words


def run_labels(runs: pl.DataFrame) -> dict[str, str]:
    """run_id -> "experiment: sweep point in words"; the experiment alone for a single run.

    Two runs that would read the same (a sweep over a non-scalar the words do not show) keep
    the run id's end to tell them apart.
    """
    if runs.is_empty():
        return {}
    table = with_parameters(runs)
    out: dict[str, str] = {}
    for experiment in table["experiment"].unique(maintain_order=True).to_list():
        params = study_parameters(runs, experiment)
        rows = table.filter(pl.col("experiment") == experiment)
        for row in rows.iter_rows(named=True):
            words = [parameter_words(p, row[p]) for p in params if row.get(p) is not None]
            out[row["run_id"]] = f"{experiment}: {', '.join(words)}" if words else experiment
    seen: dict[str, int] = {}
    for label in out.values():
        seen[label] = seen.get(label, 0) + 1
    return {
        run_id: label if seen[label] == 1 else f"{label} ({run_id.rsplit('-', 1)[-1]})"
        for run_id, label in out.items()
    }


def with_labels(frame: pl.DataFrame, labels: dict[str, str]) -> pl.DataFrame:
    """The frame with a `run` column (the readable label) first, when it has run ids."""
    if "run_id" not in frame.columns or frame.is_empty():
        return frame
    run = pl.col("run_id").replace_strict(labels, default=pl.col("run_id"), return_dtype=pl.String)
    return frame.with_columns(run.alias("run")).select("run", pl.exclude("run"))
