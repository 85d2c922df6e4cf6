"""Run labels: the experiment and its sweep point in words and units, one rule for every stage."""

from __future__ import annotations

import json
import re
from collections.abc import Collection, Mapping

import polars as pl

_AXES = "xyz"
_UNITS = {"pos": "m", "vel": "m/s", "mass": "kg", "radius": "m", "size": "m"}


def parameter_words(key: str, value: object) -> str:
    """One sweep parameter in words and units, e.g. `ball.pos[2]` = 3 -> "ball at z = 3 m"."""
    shown = f"{value:g}" if isinstance(value, float) else str(value)
    match = re.fullmatch(r"(?:bodies\.)?(\w+)\.(pos|vel)\[(\d)\]", key)
    if match:
        body, what, axis = match.groups()
        if what == "pos":
            return f"{body} released at {_AXES[int(axis)]} = {shown} m"
        return f"{body} v{_AXES[int(axis)]} = {shown} m/s"
    match = re.fullmatch(r"(?:bodies\.)?(\w+)\.(mass|radius)", key)
    if match:
        body, what = match.groups()
        return f"{body} {what} = {shown} {_UNITS[what]}"
    if key.startswith("contact."):
        return f"{key.removeprefix('contact.')} = {shown}"
    return f"{key} = {shown}"


def run_label(
    experiment: str,
    sweep: Mapping[str, object],
    varying: Mapping[str, Collection[int]] | None = None,
) -> str:
    """A run's label: "experiment: its sweep point in words and units" ("drop: ball released
    at z = 3 m"), or the experiment alone for a run not swept. A swept vector shows its
    components in `varying` (key -> indices), else those not zero (all of them when every one
    is zero)."""
    words = []
    for key, value in sweep.items():
        if isinstance(value, list | tuple):
            shown = [i for i in sorted((varying or {}).get(key, ())) if i < len(value)]
            shown = shown or [i for i, x in enumerate(value) if x]
            words += [parameter_words(f"{key}[{i}]", value[i]) for i in shown or range(len(value))]
        else:
            words.append(parameter_words(key, value))
    return f"{experiment}: {', '.join(words)}" if words else experiment


def run_labels(runs: pl.DataFrame) -> pl.DataFrame:
    """(run_id, run): `run_label` of each run of `runs` (run_id, experiment, sweep: the
    sweep point as JSON), once per run id; a swept vector shows the components that differ
    among its experiment's runs, and two runs that would read the same keep their run id's
    end ("drop: ball released at z = 1 m (c08cac40)")."""
    table = runs.select("run_id", "experiment", "sweep").unique("run_id", keep="last")
    points = table.select("experiment", "sweep")
    first: dict[tuple[str, str], list[object]] = {}
    varying: dict[str, dict[str, set[int]]] = {}
    for experiment, text in points.iter_rows():  # parsed twice, never all held at once
        for key, value in json.loads(text or "{}").items():
            if isinstance(value, list):
                seen = first.setdefault((experiment, key), value)
                differ = varying.setdefault(experiment, {}).setdefault(key, set())
                differ.update(i for i, x in enumerate(value) if seen[i : i + 1] != [x])
    words = [run_label(e, json.loads(s or "{}"), varying.get(e)) for e, s in points.iter_rows()]
    labels = table.select("run_id", pl.Series("run", words, dtype=pl.String))
    twice = pl.len().over("run") > 1
    end = pl.col("run_id").str.split("-").list.last()
    return labels.with_columns(
        pl.when(twice).then(pl.col("run") + " (" + end + ")").otherwise(pl.col("run")).alias("run")
    )
