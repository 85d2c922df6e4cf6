"""Two tables compared within tolerances: joined on their keys, each number's difference."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import polars as pl
from numpy.typing import ArrayLike

from impactlab.tools import DEFAULT_ATOL, DEFAULT_RTOL

NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:inf|nan)\b")


@dataclass(frozen=True)
class Tolerance:
    """When two numbers are equal: `|a - b| <= atol + rtol * max(|a|, |b|)`. `fields`: absolute
    tolerances replacing `atol` for a field (`z`: in every channel) or `TOPIC:FIELD`."""

    atol: float = DEFAULT_ATOL
    rtol: float = DEFAULT_RTOL
    fields: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name, value in [("atol", self.atol), ("rtol", self.rtol), *self.fields.items()]:
            if not (value >= 0 and math.isfinite(value)):
                raise ValueError(f"tolerance {name} must be finite and >= 0, got {value}")

    def atol_for(self, channel: str, name: str) -> float:
        """The absolute tolerance of one field of one channel."""
        return self.fields.get(f"{channel}:{name}", self.fields.get(name, self.atol))

    def close(self, a: ArrayLike, b: ArrayLike) -> bool:
        """Every number of `a` equal to `b`'s within the tolerance (NaN equals NaN; an
        infinity only itself)."""
        x, y = np.asarray(a, np.float64), np.asarray(b, np.float64)
        with np.errstate(all="ignore"):  # inf - inf, overflow: not finite, never within
            within = np.abs(x - y) <= self.atol + self.rtol * np.maximum(np.abs(x), np.abs(y))
        finite = np.isfinite(x) & np.isfinite(y)
        return bool(np.all((x == y) | (np.isnan(x) & np.isnan(y)) | (within & finite)))


EXACT = Tolerance(atol=0.0, rtol=0.0)


def differences(
    a: pl.DataFrame, b: pl.DataFrame, on: Sequence[str], columns: Mapping[str, tuple[float, float]]
) -> pl.DataFrame:
    """The rows of `a` and `b` with the same keys `on`, sorted, and per compared column `c`
    (with its (atol, rtol)) its value in B `c_b`, `c_d` = |a - b| (0 when equal: NaN equals
    NaN, null null; inf when only one is a number), `c_tol` and `c_beyond`: beyond the
    tolerance, or not finite, or text that differs."""
    joined = a.join(b, on=list(on), how="inner", suffix="_b", nulls_equal=True).sort(on)
    columns_out = []
    for c, (atol, rtol) in columns.items():
        x, y = pl.col(c), pl.col(f"{c}_b")
        if not joined.schema[c].is_numeric():
            columns_out.append(x.ne_missing(y).alias(f"{c}_beyond"))
            continue
        x, y, same = x.cast(pl.Float64), y.cast(pl.Float64), x.eq_missing(y)
        d = pl.when(same).then(0.0).otherwise((x - y).abs().fill_nan(math.inf).fill_null(math.inf))
        tol = atol + rtol * pl.max_horizontal(x.abs(), y.abs()).fill_null(0.0)
        beyond = ~same & (
            (d > tol) | ~x.is_finite().fill_null(False) | ~y.is_finite().fill_null(False)
        )
        columns_out += [d.alias(f"{c}_d"), tol.alias(f"{c}_tol"), beyond.alias(f"{c}_beyond")]
    return joined.with_columns(columns_out)


def same_json(a: Any, b: Any, tolerance: Tolerance = EXACT) -> bool:
    """Equal JSON values, fractional numbers within the tolerance (whole ones exactly)."""
    if isinstance(a, float) and isinstance(b, float):
        return tolerance.close(a, b)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_json(a[k], b[k], tolerance) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(map(same_json, a, b, [tolerance] * len(a)))
    return type(a) is type(b) and a == b


def flatten(value: Any, prefix: str = "") -> dict[str, Any]:
    """Nested dicts and lists of containers as {dotted path: leaf}; scalar lists are leaves."""
    if isinstance(value, dict) and value:
        items = [(f"{prefix}.{k}" if prefix else str(k), v) for k, v in value.items()]
    elif isinstance(value, list) and any(isinstance(v, dict | list) for v in value):
        items = [(f"{prefix}[{i}]", v) for i, v in enumerate(value)]
    else:
        return {prefix: value}
    return {path: leaf for k, v in items for path, leaf in flatten(v, k).items()}


def same_text(a: str, b: str, tolerance: Tolerance = EXACT) -> bool:
    """Equal texts, the numbers in them within the tolerance and the rest exactly."""
    return a == b or (
        NUMBER.split(a) == NUMBER.split(b)
        and tolerance.close(*(list(map(float, NUMBER.findall(t))) for t in (a, b)))
    )


def parse_json(text: str | None) -> Any:
    """A stored value's JSON, or `ABSENT` when it is none."""
    try:
        return json.loads(text) if text is not None else ABSENT
    except (ValueError, RecursionError):
        return ABSENT


ABSENT = object()
