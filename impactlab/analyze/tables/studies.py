"""Parameter studies: the runs table with each run's sweep parameters as columns.

A sweep value that is a list (e.g. `contact.solimp` = [0.9, 0.95, 0.001]) becomes one column per
element that varies across the experiment's runs (`contact.solimp[0]`); a scalar value becomes
one column named by its dotted path. So a sweep reads as a table: one row per run, its
parameters, its results.
"""

from __future__ import annotations

import json
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
    # one list per parameter, filled run by run (_ABSENT where a run lacks it): the values
    # in columns, never a dict per run; run ids stay in polars, experiments as small codes
    # (a run id given twice, one log in two folders, is one sweep point)
    table = runs.select("run_id", "experiment", "sweep").unique("run_id", maintain_order=True)
    experiments = table["experiment"].cast(pl.Categorical).to_physical().to_list()
    found: dict[str, list[Any]] = {}
    for n, sweep in enumerate(table["sweep"]):
        for key, value in json.loads(sweep or "{}").items():
            if "." not in key and (key in runs.columns or key == "__experiment"):
                key = f"sweep.{key}"  # a top-level spec key: `description`, `name`
            items = enumerate(value) if isinstance(value, list) else [(None, value)]
            for i, item in items:
                name = key if i is None else f"{key}[{i}]"
                column = found.setdefault(name, [])
                column.extend([_ABSENT] * (n - len(column)))
                column.append(item)
    columns: dict[str, Any] = {"run_id": table["run_id"]}
    for key in sorted(found):
        column = found.pop(key)
        column.extend([_ABSENT] * (table.height - len(column)))
        if "[" in key and not _varies(column, experiments):
            continue  # a list element that is the same in every run of every experiment
        columns[key] = [None if c is _ABSENT else c for c in column]
    schema = {k: pl.String if k == "run_id" else _dtype(col) for k, col in columns.items()}
    for key, dtype in schema.items():
        if dtype == pl.String and key != "run_id":
            columns[key] = [
                c if c is None or isinstance(c, str) else json.dumps(c) for c in columns[key]
            ]
    return pl.DataFrame(columns, schema=schema, strict=False)


_ABSENT = object()
"""A run's value of a parameter its sweep does not set (`sweep_parameters`)."""


def _varies(column: list[Any], experiments: list[int]) -> bool:
    """Whether some experiment's runs that set the parameter set it to different values."""
    first: dict[int, str] = {}
    for value, experiment in zip(column, experiments, strict=True):
        if value is _ABSENT:
            continue
        text = json.dumps(value)
        if first.setdefault(experiment, text) != text:
            return True
    return False


def _dtype(column: list[Any]) -> PolarsDataType:
    present = [c for c in column if c is not None]
    if present and all(isinstance(c, int | float) and not isinstance(c, bool) for c in present):
        return pl.Float64
    return pl.String


def parameters(runs: pl.DataFrame) -> tuple[list[str], pl.DataFrame]:
    """The runs table's sweep parameter columns, and the table with them after its own (set
    anew on a table that has them already), sorted by experiment and parameters."""
    params = sweep_parameters(runs)
    cols = [c for c in params.columns if c != "run_id"]
    base = runs.drop(cols, strict=False)
    if params.height == runs.height:  # a row per run, in the table's order: set side by side
        joined = base.hstack(params.drop("run_id").get_columns())
    else:  # a run id given twice
        joined = base.join(params, on="run_id", how="left")
    return cols, joined.sort(["experiment", *cols, "run_id"], nulls_last=True)


def study_parameters(runs: pl.DataFrame, experiment: str) -> list[str]:
    """Parameter columns of one experiment that vary across its runs."""
    params, joined = parameters(runs)
    return _varying(params, joined.filter(pl.col("experiment") == experiment))


def _varying(params: list[str], runs: pl.DataFrame) -> list[str]:
    return [p for p in params if runs[p].drop_nulls().n_unique() > 1]


def studies(runs: pl.DataFrame, params: list[str]) -> dict[str, pl.DataFrame]:
    """Per experiment whose runs differ in a sweep parameter, its study table: one row per
    run, its varying parameters and its results (`runs`, `params`: as `parameters` gives)."""
    out = {}
    for experiment in runs["experiment"].unique(maintain_order=True).to_list():
        sub = runs.filter(pl.col("experiment") == experiment)
        varying = _varying(params, sub)
        if not varying:
            continue
        dropped = _defined(sub, "first_impact_speed_mps")  # bounce results for drops only
        results = (*(BOUNCE_RESULTS if dropped else ()), *COLLISION_RESULTS)
        shown = [c for c in results if _defined(sub, c)]
        out[experiment] = sub.select("run_id", *varying, *shown, "partial", "note").sort(varying)
    return out


def _defined(frame: pl.DataFrame, column: str) -> bool:
    return column in frame.columns and frame[column].drop_nulls().len() > 0
