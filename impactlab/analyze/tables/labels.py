"""The runs' labels as a column (`impactlab.logs.labels`): "drop: ball released at z = 3 m"."""

from __future__ import annotations

import json

import polars as pl

from impactlab.logs.labels import run_labels as label_runs


def run_labels(runs: pl.DataFrame) -> pl.DataFrame:
    """(run_id, run): each run's label (`impactlab.logs.labels.run_labels`)."""
    rows = runs.select("run_id", "experiment", "sweep").iter_rows() if runs.height else ()
    labels = label_runs((r, e, json.loads(s or "{}")) for r, e, s in rows)
    return pl.DataFrame(
        {"run_id": list(labels), "run": list(labels.values())},
        schema={"run_id": pl.String, "run": pl.String},
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
