"""Expand an experiment spec into runs: command-line overrides, then the `[sweep]` grid.

`[sweep]` maps dotted field paths to lists of values; the runs are their Cartesian product,
in the order the keys are written. `--set PATH=VALUE` overrides a field (VALUE is a TOML
value: `2`, `[0, 0, 1]`, `"RK4"`); overriding a swept field replaces its list.
"""

from __future__ import annotations

import copy
import itertools
import math
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from impactlab.errors import SpecError
from impactlab.record.spec import (
    RunSpec,
    merge_defaults,
    read_toml,
    resolve_path,
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
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
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
    sweep = {".".join(resolve_path(doc, key)): values for key, values in sweep.items()}
    for text in overrides:
        key, value = parse_override(text)
        full = ".".join(resolve_path(doc, key))
        if full in sweep:
            sweep[full] = value if isinstance(value, list) else [value]
        else:
            set_path(doc, key, value, "--set")
    return expand(doc, sweep, source)


def expand(doc: Mapping[str, Any], sweep: Mapping[str, Any], source: str) -> list[RunSpec]:
    """One validated run per point of the sweep grid (one run when the sweep is empty)."""
    for key, values in sweep.items():
        if not isinstance(values, list) or not values:
            raise SpecError(source, f"sweep.{key}", "must be a non-empty list of values")
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
