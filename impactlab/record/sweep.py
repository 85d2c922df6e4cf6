"""Expand an experiment spec into runs: command-line overrides, then the `[sweep]` grid.

`[sweep]` maps dotted field paths to lists of values; the runs are their Cartesian product,
in the order the keys are written. `--set PATH=VALUE` overrides a field (VALUE is a TOML
value: `2`, `[0, 0, 1]`, `"RK4"`); overriding a swept field replaces its list: with one value
(`--set ball.pos=[0, 0, 1]`, one run) or a list of values (`--set 'ball.pos=[[0, 0, 1],
[0, 0, 2]]'`). A path names a value, never a table (`contact`, `ball`): set its fields.
"""

from __future__ import annotations

import copy
import itertools
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from impactlab.errors import SpecError
from impactlab.record.schema import short
from impactlab.record.spec import (
    RunSpec,
    check_path,
    is_list_valued,
    merge_defaults,
    parse_toml,
    read_toml,
    set_path,
    validate,
)


def parse_override(text: str, source: str = "--set") -> tuple[str, Any]:
    """Parse `PATH=VALUE` where VALUE is a TOML value (bare words are taken as strings)."""
    path, sep, raw = text.partition("=")
    path = path.strip()
    if not sep or not path:
        raise SpecError(source, text, "expected PATH=VALUE, e.g. ball.mass=2")
    try:
        value = parse_toml(f"v = {raw.strip()}", source, path)["v"]
    except SpecError as exc:
        if "nested too deeply" in exc.problem:
            raise
        value = raw.strip()
    return path, value


def load_runs(path: Path, overrides: Sequence[str] = ()) -> list[RunSpec]:
    """Read a spec file and return its runs, validated, with overrides applied."""
    return document_runs(read_toml(path), str(path), overrides)


def document_runs(
    raw: Mapping[str, Any], source: str, overrides: Sequence[str] = ()
) -> list[RunSpec]:
    """The runs of a spec document (a TOML file's content as a dict), validated.

    `source` names the document in errors and in the log (a file path, or e.g. "<python>").
    """
    if not isinstance(raw, Mapping):
        raise SpecError(source, "", f"a spec must be a table, got {type(raw).__name__}")
    sweep = raw.get("sweep", {})
    if not isinstance(sweep, Mapping):
        raise SpecError(source, "sweep", f"must be a table, got {type(sweep).__name__}")
    doc = merge_defaults(raw, source)
    swept: dict[str, list[Any]] = {}
    for key, values in sweep.items():
        keys, _ = check_path(doc, str(key), f"{source}: sweep")
        swept[".".join(keys)] = values
    for text in overrides:
        key, value = parse_override(text)
        keys, annotation = check_path(doc, key, "--set")
        full = ".".join(keys)
        if full in swept:  # one value, or a list of values to sweep
            many = isinstance(value, list) and (
                not is_list_valued(annotation) or all(isinstance(v, list) for v in value)
            )
            swept[full] = value if many else [value]
        else:
            set_path(doc, key, value, "--set")
    return expand(doc, swept, source)


def expand(doc: Mapping[str, Any], sweep: Mapping[str, Any], source: str) -> list[RunSpec]:
    """One validated run per point of the sweep grid (one run when the sweep is empty)."""
    for key, values in sweep.items():
        if not isinstance(values, list) or not values:
            raise SpecError(
                source, f"sweep.{key}", f"must be a non-empty list of values, got {short(values)}"
            )
        seen = set()
        for value in values:
            frozen = _hashable(value)
            if frozen in seen:
                raise SpecError(source, f"sweep.{key}", f"lists {short(value)} twice")
            seen.add(frozen)
    keys = list(sweep)
    runs = []
    size = math.prod(len(sweep[k]) for k in keys)
    for index, point in enumerate(itertools.product(*(sweep[k] for k in keys))):
        values = dict(zip(keys, point, strict=True))
        run_doc = copy.deepcopy(dict(doc))
        for key, value in values.items():
            set_path(run_doc, key, value, f"{source}: sweep")
        runs.append(
            validate(run_doc, source=source, sweep_values=values, sweep_point=(index, size))
        )
    return runs


def _hashable(value: Any) -> Any:
    """A value as a hashable key, equal for equal values (1 and 1.0 alike)."""
    if isinstance(value, list | tuple):
        return tuple(_hashable(v) for v in value)
    if isinstance(value, Mapping):
        return tuple(sorted((str(k), _hashable(v)) for k, v in value.items()))
    return value
