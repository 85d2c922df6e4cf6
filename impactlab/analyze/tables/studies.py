"""Parameter studies: the runs table with each run's sweep parameters as columns.

A sweep value that is a list (e.g. `contact.solimp` = [0.9, 0.95, 0.001]) becomes one column per
element that varies across the experiment's runs (`contact.solimp[0]`); a scalar value becomes
one column named by its dotted path. So a sweep reads as a table: one row per run, its
parameters, its results.
"""

from __future__ import annotations

import json
import weakref
from typing import TYPE_CHECKING, Any

import polars as pl

if TYPE_CHECKING:
    from polars._typing import PolarsDataType

BOUNCE_RESULTS = (
    "drop_height_m",
    "first_impact_speed_mps",
    "n_bounces_complete",
    "e_velocity_first",
    "e_velocity_mean",
    "e_apex_mean",
    "energy_loss_frac",
)
COLLISION_RESULTS = (
    "e_collision",
    "v1n_before_mps",
    "v2n_before_mps",
    "v1n_after_mps",
    "v2n_after_mps",
    "v1n_after_elastic_mps",
    "v2n_after_elastic_mps",
    "momentum_rel_change",
    "collision_ke_loss_frac",
)


def sweep_parameters(runs: pl.DataFrame) -> pl.DataFrame:
    """(run_id, <param columns>) from the runs table's `sweep` JSON, varying elements only.

    A swept top-level key that is also a column of the runs table (`description`) is named
    `sweep.<key>`.
    """
    values: dict[str, dict[str, Any]] = {}
    for run_id, experiment, sweep in runs.select("run_id", "experiment", "sweep").iter_rows():
        point = json.loads(sweep or "{}")
        values[run_id] = {"__experiment": experiment}
        for key, value in point.items():
            if "." not in key and (key in runs.columns or key == "__experiment"):
                key = f"sweep.{key}"  # a top-level spec key: `description`, `name`
            if isinstance(value, list):
                for i, item in enumerate(value):
                    values[run_id][f"{key}[{i}]"] = item
            else:
                values[run_id][key] = value
    columns: dict[str, list[Any]] = {"run_id": list(values)}
    keys = sorted({k for v in values.values() for k in v if k != "__experiment"})
    for key in keys:
        by_exp: dict[str, set[str]] = {}
        for v in values.values():
            if key in v:
                by_exp.setdefault(v["__experiment"], set()).add(json.dumps(v[key]))
        if not any(len(s) > 1 for s in by_exp.values()) and "[" in key:
            continue  # a list element that is the same in every run of every experiment
        columns[key] = [v.get(key) for v in values.values()]
    schema = {k: _dtype(col) for k, col in columns.items()}
    for key, dtype in schema.items():
        if dtype == pl.String and key != "run_id":
            columns[key] = [
                c if c is None or isinstance(c, str) else json.dumps(c) for c in columns[key]
            ]
    return pl.DataFrame(columns, schema=schema, strict=False)


def _dtype(column: list[Any]) -> PolarsDataType:
    present = [c for c in column if c is not None]
    if present and all(isinstance(c, int | float) and not isinstance(c, bool) for c in present):
        return pl.Float64
    return pl.String


def with_parameters(runs: pl.DataFrame) -> pl.DataFrame:
    """The runs table with its sweep parameter columns after `sweep`."""
    return _parameters(runs)[1]


_LAST: list[tuple[weakref.ref[pl.DataFrame], list[str], pl.DataFrame]] = []


def _parameters(runs: pl.DataFrame) -> tuple[list[str], pl.DataFrame]:
    """The runs table's sweep parameter columns and `with_parameters`, computed once per
    table object while it lives (the report, the studies and the labels each ask for them,
    per experiment: the sweep JSON of every run was parsed again each time)."""
    for ref, cols, joined in _LAST:
        if ref() is runs:
            return cols, joined
    params = sweep_parameters(runs)
    cols = [c for c in params.columns if c != "run_id"]
    joined = runs.join(params, on="run_id", how="left").sort(
        ["experiment", *cols, "run_id"], nulls_last=True
    )
    _LAST[:] = [(weakref.ref(runs, _forget), cols, joined)]
    return cols, joined


def _forget(ref: weakref.ref[pl.DataFrame]) -> None:
    """Drop the cached table with the runs table it was made from."""
    if _LAST and _LAST[0][0] is ref:
        _LAST.clear()


def study_parameters(runs: pl.DataFrame, experiment: str) -> list[str]:
    """Parameter columns of one experiment that vary across its runs."""
    params, joined = _parameters(runs)
    sub = joined.filter(pl.col("experiment") == experiment)
    return [p for p in params if sub[p].drop_nulls().n_unique() > 1]


def study_table(runs: pl.DataFrame, experiment: str) -> pl.DataFrame:
    """One row per run of a swept experiment: its varying parameters and its results."""
    params = study_parameters(runs, experiment)
    sub = with_parameters(runs).filter(pl.col("experiment") == experiment)
    results = [
        c
        for c in (*BOUNCE_RESULTS, *COLLISION_RESULTS)
        if c in sub.columns and sub[c].drop_nulls().len() > 0
    ]
    return sub.select("run_id", *params, *results, "partial", "note").sort(params or "run_id")


def studies(runs: pl.DataFrame) -> dict[str, pl.DataFrame]:
    """Per experiment with at least two runs that differ in a sweep parameter, its study table."""
    out = {}
    for experiment in runs["experiment"].unique(maintain_order=True).to_list():
        if study_parameters(runs, experiment):
            out[experiment] = study_table(runs, experiment)
    return out
