"""Readable run labels: the experiment and its sweep point in words and units.

A run id carries a hash (`drop-ball.pos=0_0_3-c08cac40`); a reader wants "drop: ball released
at z = 3 m". The hash stays in the report's details table only.
"""

from __future__ import annotations

import functools

import polars as pl

from impactlab.analyze.tables.studies import study_parameters, with_parameters
from impactlab.logs.labels import parameter_words


def run_labels(runs: pl.DataFrame) -> pl.DataFrame:
    """(run_id, run): each run's label, "experiment: sweep point in words"; the experiment
    alone for a single run. In columns: a sweep's labels are never a Python object per run.

    Two runs that would read the same (a sweep over a non-scalar the words do not show) keep
    the run id's end to tell them apart.
    """
    if runs.is_empty():
        return pl.DataFrame(schema={"run_id": pl.String, "run": pl.String})
    table = with_parameters(runs).unique("run_id", keep="last", maintain_order=True)
    pieces = []
    for experiment in table["experiment"].unique(maintain_order=True).to_list():
        params = study_parameters(runs, experiment)
        rows = table.filter(pl.col("experiment") == experiment)
        words = [
            rows[p].map_elements(
                functools.partial(parameter_words, p), return_dtype=pl.String, skip_nulls=True
            )
            for p in params
        ]
        named = pl.lit(experiment, dtype=pl.String)
        if words:
            text = pl.concat_str(words, separator=", ", ignore_nulls=True)
            said = text.is_not_null() & (text != "")
            named = pl.when(said).then(pl.lit(f"{experiment}: ") + text).otherwise(named)
        pieces.append(rows.select("run_id", named.alias("run")))
    labels = pl.concat(pieces)
    end = pl.col("run_id").str.split("-").list.last()
    twice = pl.len().over("run") > 1
    return labels.with_columns(
        pl.when(twice).then(pl.col("run") + " (" + end + ")").otherwise(pl.col("run")).alias("run")
    )


def with_labels(frame: pl.DataFrame, labels: pl.DataFrame) -> pl.DataFrame:
    """The frame with a `run` column (the readable label of `run_labels`) first, when it has
    run ids."""
    if "run_id" not in frame.columns or frame.is_empty():
        return frame
    run = pl.col("run_id").replace_strict(
        labels["run_id"], labels["run"], default=pl.col("run_id"), return_dtype=pl.String
    )
    return frame.with_columns(run.alias("run")).select("run", pl.exclude("run"))
