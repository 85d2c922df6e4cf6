"""Expand an experiment spec into runs: command-line overrides, then the `[sweep]` grid."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from impactlab.errors import SpecError
from impactlab.record.schema import MAX_LOG_EVERY, MAX_TIME_S, MIN_TIMESTEP_S, short
from impactlab.record.spec import (
    RunSpec,
    check_path,
    is_list_valued,
    merge_defaults,
    parse_toml,
    plain_copy,
    read_toml,
    set_path,
    validate,
)
from impactlab.record.work import MAX_RUNS, Work, run_steps


def parse_override(text: str, source: str = "--set") -> tuple[str, Any]:
    """Parse `PATH=VALUE` where VALUE is a TOML value (bare words are taken as strings)."""
    if "\n" in text or "\r" in text:
        raise SpecError(
            source,
            text.splitlines()[0],  # a text with a line break has one line at least
            "holds a line break: give one PATH=VALUE per --set (a TOML value on one line)",
        )
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
    return list(SpecSweep.read(path, overrides).iter_runs())


@dataclass(frozen=True)
class SpecSweep:
    """A spec document with its overrides applied and its sweep checked, not yet expanded.

    `source` names the document in errors and in the log (a file path, or e.g. "<python>").
    """

    doc: dict[str, Any]
    sweep: dict[str, list[Any]]
    source: str

    @classmethod
    def read(cls, path: Path, overrides: Sequence[str] = ()) -> SpecSweep:
        """A spec file's sweep, overrides applied."""
        return cls.of(read_toml(path), str(path), overrides)

    @classmethod
    def of(cls, raw: Mapping[str, Any], source: str, overrides: Sequence[str] = ()) -> SpecSweep:
        """A spec document's (a TOML file's content as a dict) sweep, overrides applied."""
        doc, sweep = _prepare(raw, source, overrides)
        check_sweep(sweep, source)
        return cls(doc, sweep, source)

    def __len__(self) -> int:
        return math.prod(len(v) for v in self.sweep.values())

    def work(self) -> Work:
        """The work its runs ask for at most, without expanding the sweep."""
        varied = [k for k in WORK_FIELDS if k in self.sweep]
        if len(self) > MAX_RUNS:  # every list of values holds one at least (`check_sweep`)
            return Work(runs=len(self))  # refused on its count alone
        others = len(self) // math.prod(len(self.sweep[k]) for k in varied)
        total = Work()
        for point in itertools.product(*(self.sweep[k] for k in varied)):
            values = dict(zip(varied, point, strict=True))
            dt, max_time, every = (values.get(k, _get(self.doc, k)) for k in WORK_FIELDS)
            if not (
                all(_positive(x) for x in (dt, max_time, every))
                and dt >= MIN_TIMESTEP_S
                and max_time <= MAX_TIME_S
                and every <= MAX_LOG_EVERY
            ):
                continue  # not a valid value: validation names it
            steps = run_steps(float(max_time), float(dt))
            total += Work.of_runs(others, steps, int(every), len(self.doc["bodies"]))
        return total

    def iter_runs(self) -> Iterator[RunSpec]:
        """Every run of the sweep, validated one at a time (a large sweep is never held)."""
        return map(self.run, range(len(self)))

    def run(self, index: int) -> RunSpec:
        """The sweep's point `index` (0 <= index < len(self)), validated; the points are in
        the order of the grid's product, the last swept key varying fastest."""
        point, rest = {}, index
        for key in reversed(self.sweep):
            rest, i = divmod(rest, len(self.sweep[key]))
            point[key] = self.sweep[key][i]
        values = {key: point[key] for key in self.sweep}
        return validate(
            _with_values(self.doc, values),
            source=self.source,
            sweep_values=values,
            sweep_point=(index, len(self)),
        )


WORK_FIELDS = ("options.timestep", "stop.max_time", "logging.every")


def _get(doc: Mapping[str, Any], path: str) -> Any:
    section, key = path.split(".")  # a section of a merged document is a table
    return doc[section].get(key)


def _positive(value: Any) -> bool:
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(value)
        and value > 0
    )


def _prepare(
    raw: Mapping[str, Any], source: str, overrides: Sequence[str]
) -> tuple[dict[str, Any], dict[str, list[Any]]]:
    """The resolved document and the sweep (resolved paths -> values), overrides applied."""
    if not isinstance(raw, Mapping):
        raise SpecError(source, "", f"a spec must be a table, got {type(raw).__name__}")
    sweep = raw.get("sweep", {})
    if not isinstance(sweep, Mapping):
        raise SpecError(source, "sweep", f"must be a table, got {type(sweep).__name__}")
    doc = merge_defaults(raw, source)
    swept: dict[str, list[Any]] = {}
    for key, values in sweep.items():
        keys, _ = check_path(doc, str(key), f"{source}: sweep")
        full = ".".join(keys)
        if full in swept:
            raise SpecError(source, f"sweep.{key}", f"sweeps {full} a second time")
        swept[full] = values
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
    return doc, swept


def check_sweep(sweep: Mapping[str, Any], source: str) -> None:
    """Each swept key's values: a non-empty list, no value twice."""
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


def _with_values(doc: Mapping[str, Any], values: Mapping[str, Any]) -> dict[str, Any]:
    """The document with one sweep point's values set (resolved paths, checked).

    Only the tables on the paths of the swept values are copied: the runs of a sweep share
    the rest of their (never changed) document, which keeps a large sweep small.
    """
    out = dict(doc)
    for path, value in values.items():
        keys = path.split(".")
        node = out
        for key in keys[:-1]:
            node[key] = dict(node[key])
            node = node[key]
        node[keys[-1]] = plain_copy(value)
    return out


def _hashable(value: Any) -> Any:
    """A value as a hashable key, equal for equal values (1 and 1.0 alike)."""
    if isinstance(value, list | tuple):
        return tuple(_hashable(v) for v in value)
    if isinstance(value, Mapping):
        return tuple(sorted((str(k), _hashable(v)) for k, v in value.items()))
    return value
