"""A log's metadata checked against its declared models (`metadata`) and against its channels."""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping
from typing import Annotated, Any

import numpy as np
from pydantic import TypeAdapter, ValidationError

from impactlab.logs import format as logformat
from impactlab.logs.metadata import (
    ANALYSIS_KEYS,
    HOLDS,
    RECORDS,
    TEXT,
)
from impactlab.physics import half_step_s
from impactlab.text import clipped

MAX_STEP_NS = 1 << 62  # timestep x log_every must stay far from int64 overflow
PLANE_GEOM = "plane"  # the plane of a spec's model, as its contact pairs name it


@functools.cache
def _validators(model: type) -> dict[str, TypeAdapter[Any]]:
    """Each field's validator, with its constraints: a key is checked on its own."""
    fields = model.__pydantic_fields__  # type: ignore[attr-defined]
    annotated: Any = Annotated  # a type built at run time: its field's type and constraints
    return {
        n: TypeAdapter(annotated[(f.annotation, *f.metadata)] if f.metadata else f.annotation)
        for n, f in fields.items()
    }


@dataclasses.dataclass(frozen=True)
class MetadataCheck:
    """What the metadata says: typed values of the keys that hold, and per key the problem."""

    values: dict[str, Any]
    problems: dict[str, str]

    def lines(self) -> list[str]:
        """One sentence per problem: `metadata <key>: <problem>`."""
        return [f"metadata {key}: {problem}" for key, problem in self.problems.items()]

    def blocking(self) -> dict[str, str]:
        """The problems on keys the analysis cannot do without (`ANALYSIS_KEYS`)."""
        return {k: p for k, p in self.problems.items() if k in ANALYSIS_KEYS}


def optional_keys(version: str | None) -> tuple[str, ...]:
    """The run record's keys a log of this format version may lack."""
    return logformat.RUN_KEYS_ADDED + (logformat.RUN_KEYS_FORMAT_2 if version == "1" else ())


def check_metadata(
    records: Mapping[str, Mapping[str, str]],
    conflicts: Mapping[str, Mapping[str, str]] | None = None,
) -> MetadataCheck:
    """Check the run and outcome records (`{record name: {key: stored value}}`) against their
    models, key by key: the typed values that hold, one problem per key that does not. A key
    missing from a record that is there is a problem, unless older logs lack it; so is a key
    that two records of one name give differently (`conflicts`, from the reader)."""
    values: dict[str, Any] = {}
    problems: dict[str, str] = {}
    optional = optional_keys(records.get(logformat.RUN_METADATA, {}).get("log_format_version"))
    for name, model in RECORDS.items():
        stored = records.get(name, {})
        for key, validator in _validators(model).items() if name in records else ():
            if key not in stored:
                if key not in optional:
                    problems[key] = f"missing from the {name} record"
                continue
            text = stored[key]
            try:  # text as is, "" as None, the rest as JSON
                if key in TEXT or not text:
                    values[key] = validator.validate_python(text if key in TEXT else None)
                else:
                    values[key] = validator.validate_json(text)
            except ValidationError as exc:
                problems[key] = _problem(key, text, exc.errors()[0])
    for name in RECORDS:
        for key, problem in (conflicts or {}).get(name, {}).items():
            values.pop(key, None)
            problems[key] = problem
    _relate(values, problems)
    return MetadataCheck(values, problems)


def _problem(key: str, text: str, error: Any) -> str:
    """`'<stored value>' <what is wrong> (expected: <what it holds>)`."""
    holds = HOLDS[key]
    if not error["loc"] and error["type"] in ("json_invalid", "float_type", "int_type"):
        words = "is not a " + ("whole number" if holds.startswith("whole") else "number")
        words = "is not valid JSON" if holds.startswith("JSON") else words
    elif error["type"] in (
        "finite_number",
        *(f"{c}_than{e}" for c in ("greater", "less") for e in ("", "_equal")),
    ):
        words = "is out of range"
    else:
        words = error["msg"].removeprefix("Value error, ").replace("Input should be ", "is not ", 1)
    where = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in error["loc"]).lstrip(".")
    return f"{_shown(text)}{f' at {where}' if where else ''} {words} (expected: {holds})"


def construction_problem(exc: ValidationError) -> str:
    """The first error of building a record's model: `<field>: <what is wrong>`."""
    error = exc.errors()[0]
    key, *rest = error["loc"] or ("?",)
    where = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in rest)
    problem = error["msg"].removeprefix("Value error, ") + (f" at {where}" if where else "")
    return f"{key}: {problem} (got {_shown(error['input'])})"


def _shown(value: Any) -> str:
    """A value as a problem quotes it, cut to 40 characters."""
    return repr(clipped(value if isinstance(value, str) else repr(value), 40))


def step_ns(timestep_s: float) -> int:
    """The timestep in integer ns, as the recorder stamps the rows (step index times this)."""
    return max(1, round(timestep_s * 1e9))


def _relate(values: dict[str, Any], problems: dict[str, str]) -> None:
    """What the keys say of each other: the sweep point, the stride, the half step."""
    index, size = values.get("sweep_index"), values.get("sweep_size")
    if index is not None and size is not None and index >= size:
        problems["sweep_index"] = f"{index} is not below sweep_size {size}"
        del values["sweep_index"], values["sweep_size"]
    dt, every, integrator = (
        values.get("timestep_s"),
        values.get("log_every"),
        values.get("integrator"),
    )
    if dt is not None and every is not None and step_ns(dt) * every > MAX_STEP_NS:
        problems["log_every"] = f"{every} steps of {dt:g} s between logged rows is out of range"
        del values["log_every"]
    if (half := values.get("half_step_s")) is not None and dt is not None and integrator:
        expected = half_step_s(integrator, dt)
        if not math.isclose(half, expected, rel_tol=1e-9, abs_tol=1e-18):
            problems["half_step_s"] = (
                f"{half:g} s, but {integrator} at dt = {dt:g} s gives {expected:g} s"
            )
            del values["half_step_s"]


def check_channels(
    check: MetadataCheck, body_times: Mapping[str, np.ndarray], *, complete: bool = True
) -> None:
    """Add to `check` what the channels contradict: `body_times`, each body channel's logged
    times (ns, sorted); `complete`: the file is intact (in a cut one a body may lack one)."""
    values, problems = check.values, check.problems
    if "bodies" in values:
        named = [b.name for b in values["bodies"]]
        parts = [f"no entry for the logged body {n!r}" for n in body_times if n not in named]
        if complete:
            parts += [
                f"{n!r} has no state channel in the log" for n in named if n not in body_times
            ]
        if parts:
            problems["bodies"] = "; ".join(parts)
            del values["bodies"]
    times = next((t for t in body_times.values() if t.size), None)
    if times is None:
        return
    if "timestep_s" in values and (off := times[times % step_ns(values["timestep_s"]) != 0]).size:
        problems["timestep_s"] = (
            f"{values['timestep_s']:g} s does not fit the logged times "
            f"(t = {off[0] / 1e9:.9g} s is not a whole number of steps)"
        )
        del values["timestep_s"]
        values.pop("log_every", None)
    if "timestep_s" in values and "log_every" in values and times.size >= 3:
        gaps, counts = np.unique(np.diff(times), return_counts=True)
        usual, dt = int(gaps[np.argmax(counts)]), step_ns(values["timestep_s"])
        if usual != dt * values["log_every"]:
            problems["log_every"] = (
                f"{values['log_every']}, but the logged rows are mostly {usual / dt:g} steps apart"
            )
            del values["log_every"]
    if "steps" in values and "timestep_s" in values:
        end_ns = values["steps"] * step_ns(values["timestep_s"])
        if int(times[-1]) > end_ns:
            problems["steps"] = (
                f"{values['steps']} steps end at t = {end_ns / 1e9:.9g} s, but the log has "
                f"rows up to t = {times[-1] / 1e9:.9g} s"
            )
            del values["steps"]
