"""The declared schema of a log's metadata, and its check against the values and the channels.

Metadata records carry no CRC, and a log may come from another tool or another version: any
value may be missing, of the wrong type, out of range, or say something the channels
contradict. `check_metadata` checks every key of the `impactlab.run` and `impactlab.outcome`
records against `KEYS` (one entry per key: what it holds, its range) and returns the values
that hold, typed, and one problem per key that does not. `check_channels` then compares what
the metadata says with what the log holds (bodies, logged times, sweep point, steps).

A problem on one of `ANALYSIS_KEYS` (masses, sizes, gravity, ground, timestep, logging stride,
integrator and its half step, the static bodies' energy) makes every energy, height and
restitution of the run untrustworthy: the analysis refuses that run and names the key. A
problem on any other key is reported, the value is treated as unknown, and the run is
analyzed. The keys added to format version 1 later (`format.RUN_KEYS_ADDED`) may be missing:
older logs do not have them. Logs of format 1 lack the keys of format 2 too
(`format.RUN_KEYS_FORMAT_2`, declared in `impactlab.logs.contract`), whose values are derived
there.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from impactlab.logs import contract
from impactlab.logs import format as logformat
from impactlab.logs.values import Invalid as Invalid  # re-exported: the parsers raise it
from impactlab.logs.values import json_value as _json
from impactlab.logs.values import number as _number
from impactlab.logs.values import quote as _quote
from impactlab.logs.values import real as _real
from impactlab.physics import INTEGRATORS as INTEGRATORS  # the names the key accepts

MAX_TIMESTEP_S = 10.0
MIN_TIMESTEP_S = 1e-9  # log times are integer ns
MAX_LOG_EVERY = 10**9
MAX_COUNT = 10**15  # steps, sweep size
MAX_MAGNITUDE = 1e6  # |gravity| in m/s^2, |plane_z| and radius in m
MAX_MASS_KG = 1e9
MAX_INERTIA = 1e12  # kg m^2
MAX_STEP_NS = 1 << 62  # timestep x log_every must stay far from int64 overflow
MAX_ENERGY_J = 1e15
OUTCOMES = ("completed", "unstable")
ANALYSIS_KEYS = (
    "timestep_s",
    "log_every",
    "bodies",
    "gravity",
    "plane_z",
    "integrator",
    "ground",
    "static_potential_J",
    "half_step_s",
)


@dataclass(frozen=True)
class Key:
    """One metadata key: the record it belongs to, what it holds, and how it is parsed.

    `parse` turns the stored string into the typed value or raises `Invalid` with the reason.
    """

    name: str
    record: str
    holds: str
    parse: Callable[[str], Any]


@dataclass(frozen=True)
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


def _text(value: str) -> str:
    return value


def _nonempty(value: str) -> str:
    if not value.strip():
        raise Invalid("empty")
    return value


def _version(value: str) -> str:
    if value not in logformat.READABLE_FORMATS:
        readable = ", ".join(logformat.READABLE_FORMATS)
        raise Invalid(f"{_quote(value)}: this impactlab reads log formats {readable}")
    return value


def _integer(low: int, high: int) -> Callable[[str], int]:
    def parse(value: str) -> int:
        text = value.strip()
        if not text.isdecimal() or len(text) > 20:
            raise Invalid(f"{_quote(value)} is not a whole number")
        number = int(text)
        if not low <= number <= high:
            raise Invalid(f"{number} is out of range")
        return number

    return parse


def _timestep(value: str) -> float:
    return _number(value, MIN_TIMESTEP_S, MAX_TIMESTEP_S)


def _plane_z(value: str) -> float | None:
    if value == "":
        return None  # no plane
    return _number(value, -MAX_MAGNITUDE, MAX_MAGNITUDE)


def _object(value: str) -> dict[str, Any]:
    parsed = _json(value)
    if not isinstance(parsed, dict):
        raise Invalid(f"{_quote(value)} is not a JSON object")
    return parsed


SPEC_SECTIONS = ("contact", "options", "plane", "stop", "logging")


def _spec(value: str) -> dict[str, Any]:
    parsed = _object(value)
    bodies = parsed.get("bodies", {})
    if not isinstance(bodies, dict) or not all(isinstance(b, dict) for b in bodies.values()):
        raise Invalid("its bodies are not a table of tables")
    for name in SPEC_SECTIONS:
        if not isinstance(parsed.get(name, {}), dict | None):
            raise Invalid(f"its {name} is not a table")
    return parsed


def _gravity(value: str) -> tuple[float, float, float]:
    parsed = _json(value)
    if not (isinstance(parsed, list) and len(parsed) == 3):
        raise Invalid(f"{_quote(value)} is not a list of 3 numbers")
    if not all(_real(g, -MAX_MAGNITUDE, MAX_MAGNITUDE) for g in parsed):
        raise Invalid(f"{_quote(value)} is out of range")
    return tuple(float(g) for g in parsed)  # type: ignore[return-value]


MOTIONS = ("free", "articulated")
"""A body's `motion` in `bodies`: a lone free body, or one of a jointed or welded tree."""


def _bodies(value: str) -> list[dict[str, Any]]:
    parsed = _json(value)
    if not isinstance(parsed, list):
        raise Invalid(f"{_quote(value)} is not a JSON list of bodies")
    names = set()
    for i, body in enumerate(parsed):
        where = f"body {i}"
        if not isinstance(body, dict) or not isinstance(body.get("name"), str) or not body["name"]:
            raise Invalid(f"{where}: no name")
        where = f"body {body['name']!r}"
        if body["name"] in names:
            raise Invalid(f"{where} is listed twice")
        names.add(body["name"])
        if not _real(body.get("mass"), 0.0, MAX_MASS_KG) or body["mass"] <= 0:
            raise Invalid(
                f"{where}: mass {_quote(body.get('mass'))} is not in (0, {MAX_MASS_KG:g}] kg"
            )
        inertia = body.get("inertia")
        if not (isinstance(inertia, list) and len(inertia) == 3) or not all(
            _real(v, 0.0, MAX_INERTIA) for v in inertia
        ):
            raise Invalid(
                f"{where}: inertia {_quote(inertia)} is not 3 numbers in [0, {MAX_INERTIA:g}]"
            )
        radius = body.get("radius")
        if radius is not None and not (_real(radius, 0.0, MAX_MAGNITUDE) and radius > 0):
            raise Invalid(f"{where}: radius {_quote(radius)} is not in (0, {MAX_MAGNITUDE:g}] m")
        rest = body.get("rest_height_m")
        if rest is not None and not _real(rest, -MAX_MAGNITUDE, MAX_MAGNITUDE):
            raise Invalid(
                f"{where}: rest_height_m {_quote(rest)} is not within +-{MAX_MAGNITUDE:g} m"
            )
        geoms = body.get("geoms", [])
        if not isinstance(body.get("shape", ""), str) or not (
            isinstance(geoms, list) and all(isinstance(g, str) for g in geoms)
        ):
            raise Invalid(f"{where}: its shape or geoms are not text")
        if body.get("motion", "free") not in MOTIONS:
            raise Invalid(f"{where}: motion {_quote(body.get('motion'))} is not one of {MOTIONS}")
    return parsed


def _ground(value: str) -> list[dict[str, Any]]:
    parsed = _json(value)
    if not isinstance(parsed, list):
        raise Invalid(f"{_quote(value)} is not a JSON list of surfaces")
    for i, surface in enumerate(parsed):
        ok = (
            isinstance(surface, dict)
            and isinstance(surface.get("name"), str)
            and isinstance(surface.get("type"), str)
            and _real(surface.get("level_m"), -MAX_MAGNITUDE, MAX_MAGNITUDE)
            and isinstance(surface.get("distance"), bool)
        )
        if not ok:
            raise Invalid(f"surface {i} is not {{name, type, level_m, distance}} in range")
    return parsed


def _integrator(value: str) -> str:
    if value not in INTEGRATORS:
        raise Invalid(f"{_quote(value)} is not one of {', '.join(INTEGRATORS)}")
    return value


def _energy(value: str) -> float:
    return _number(value, -MAX_ENERGY_J, MAX_ENERGY_J)


def _warnings(value: str) -> list[str]:
    parsed = _json(value)
    if not isinstance(parsed, list) or not all(isinstance(w, str) for w in parsed):
        raise Invalid(f"{_quote(value)} is not a JSON list of sentences")
    return parsed


def _outcome(value: str) -> str:
    if value not in OUTCOMES:
        raise Invalid(f"{_quote(value)} is not one of {', '.join(OUTCOMES)}")
    return value


RUN, OUTCOME = logformat.RUN_METADATA, logformat.OUTCOME_METADATA
KEYS: dict[str, Key] = {
    k.name: k
    for k in (
        Key("log_format_version", RUN, "the log format's version", _version),
        Key("impactlab_version", RUN, "the recorder's version", _text),
        Key("mujoco_version", RUN, "MuJoCo's version", _text),
        Key("experiment", RUN, "the experiment's name", _text),
        Key("description", RUN, "the experiment's description", _text),
        Key("source", RUN, "the spec file as given", _text),
        Key("run_id", RUN, "the run's id", _nonempty),
        Key("spec", RUN, "JSON object: the resolved spec (its sections objects too)", _spec),
        Key("sweep", RUN, "JSON object: {dotted path: value}", _object),
        Key("sweep_index", RUN, f"whole number 0 .. {MAX_COUNT:g}", _integer(0, MAX_COUNT)),
        Key("sweep_size", RUN, f"whole number 1 .. {MAX_COUNT:g}", _integer(1, MAX_COUNT)),
        Key("spec_hash", RUN, "hash of the spec", _text),
        Key("timestep_s", RUN, f"number {MIN_TIMESTEP_S:g} .. {MAX_TIMESTEP_S:g} s", _timestep),
        Key("log_every", RUN, f"whole number 1 .. {MAX_LOG_EVERY:g}", _integer(1, MAX_LOG_EVERY)),
        Key("gravity", RUN, f"JSON [gx, gy, gz], each within ±{MAX_MAGNITUDE:g} m/s^2", _gravity),
        Key(
            "bodies",
            RUN,
            "JSON [{name, mass > 0, inertia [3] >= 0, radius > 0 or null, ...}]",
            _bodies,
        ),
        Key("plane_z", RUN, f"number within ±{MAX_MAGNITUDE:g} m, or empty: no plane", _plane_z),
        Key("integrator", RUN, f"one of {', '.join(INTEGRATORS)}", _integrator),
        Key("ground", RUN, "JSON [{name, type, level_m, distance}]", _ground),
        Key("static_potential_J", RUN, f"number within ±{MAX_ENERGY_J:g} J", _energy),
        *(Key(name, RUN, holds, parse) for name, holds, parse in contract.KEYS),
        Key("outcome", OUTCOME, f"one of {', '.join(OUTCOMES)}", _outcome),
        Key("reason", OUTCOME, "why the run ended", _text),
        Key("warnings", OUTCOME, "JSON list of sentences", _warnings),
        Key("steps", OUTCOME, f"whole number 0 .. {MAX_COUNT:g}", _integer(0, MAX_COUNT)),
    )
}


def check_metadata(records: Mapping[str, Mapping[str, str]]) -> MetadataCheck:
    """Check the values of the run and outcome records (`{record name: {key: value}}`).

    A key missing from a record that is present is a problem; a missing record is not
    (the reader reports it: no run metadata, or no outcome record for an incomplete log).
    """
    values: dict[str, Any] = {}
    optional = contract.optional_keys(records.get(RUN, {}).get("log_format_version"))
    problems: dict[str, str] = {}
    for key in KEYS.values():
        record = records.get(key.record)
        if record is None:
            continue
        if key.name not in record:
            if key.name not in optional:  # older logs lack those
                problems[key.name] = f"missing from the {key.record} record"
            continue
        try:
            values[key.name] = key.parse(record[key.name])
        except Invalid as exc:
            problems[key.name] = f"{exc} (expected: {key.holds})"
    index, size = values.get("sweep_index"), values.get("sweep_size")
    if index is not None and size is not None and index >= size:
        problems["sweep_index"] = f"{index} is not below sweep_size {size}"
        del values["sweep_index"], values["sweep_size"]
    dt, every = values.get("timestep_s"), values.get("log_every")
    if dt is not None and every is not None and step_ns(dt) * every > MAX_STEP_NS:
        problems["log_every"] = f"{every} steps of {dt:g} s between logged rows is out of range"
        del values["log_every"]
    contract.settle(values, problems)  # format 1: its keys derived
    return MetadataCheck(values, problems)


def step_ns(timestep_s: float) -> int:
    """The timestep in integer ns, as the recorder stamps the rows (step index times this)."""
    return max(1, round(timestep_s * 1e9))


def check_channels(
    check: MetadataCheck, body_times: Mapping[str, np.ndarray], *, complete: bool = True
) -> None:
    """Add to `check` what the metadata says that the channels contradict.

    Args:
        check: the checked metadata (its values and problems are updated).
        body_times: per body channel, its logged times in ns, sorted, (nrow,).
        complete: the file is intact; in a truncated one a body may have no channel yet.
    """
    values, problems = check.values, check.problems
    if "bodies" in values:
        named = [b["name"] for b in values["bodies"]]
        unknown = [n for n in body_times if n not in named]
        absent = [n for n in named if n not in body_times] if complete else []
        if unknown or absent:
            parts = [f"no entry for the logged body {n!r}" for n in unknown]
            parts += [f"{n!r} has no state channel in the log" for n in absent]
            problems["bodies"] = "; ".join(parts)
            del values["bodies"]
    times = next((t for t in body_times.values() if t.size), None)
    if times is None:
        return
    if "timestep_s" in values:
        dt = step_ns(values["timestep_s"])
        off = times[times % dt != 0]
        if off.size:
            problems["timestep_s"] = (
                f"{values['timestep_s']:g} s does not fit the logged times "
                f"(t = {off[0] / 1e9:.9g} s is not a whole number of steps)"
            )
            del values["timestep_s"]
            values.pop("log_every", None)
    if "timestep_s" in values and "log_every" in values and times.size >= 3:
        gaps, counts = np.unique(np.diff(times), return_counts=True)
        usual = int(gaps[np.argmax(counts)])
        logged = step_ns(values["timestep_s"]) * values["log_every"]
        if usual != logged:
            problems["log_every"] = (
                f"{values['log_every']}, but the logged rows are mostly "
                f"{usual / step_ns(values['timestep_s']):g} steps apart"
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
