"""Checks of a log's metadata values: the records carry no CRC, so a damaged byte can leave a
value that does not parse."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import numpy as np


def metadata_problem(meta: dict[str, str]) -> str | None:
    """What is wrong with the values of the run and outcome metadata, or None.

    Metadata records carry no CRC: a damaged byte can leave a value that does not parse.
    Keys that are absent are not checked (the callers handle them).
    """

    def number(text: str) -> bool:
        try:
            return np.isfinite(float(text))
        except ValueError:
            return False

    def integer(text: str) -> bool:
        return text.isdigit()

    def vector(value: Any) -> bool:
        return isinstance(value, list) and len(value) == 3 and all(_real(v) for v in value)

    def body(value: Any) -> bool:
        return (
            isinstance(value, dict)
            and isinstance(value.get("name"), str)
            and _real(value.get("mass"))
            and vector(value.get("inertia"))
            and (value.get("radius") is None or _real(value.get("radius")))
            and (value.get("rest_height_m") is None or _real(value.get("rest_height_m")))
            and isinstance(value.get("shape", ""), str)
            and isinstance(value.get("geoms", []), list)
            and all(isinstance(g, str) for g in value.get("geoms", []))
        )

    def surface(value: Any) -> bool:
        return (
            isinstance(value, dict)
            and isinstance(value.get("name"), str)
            and isinstance(value.get("type"), str)
            and _real(value.get("level_m"))
            and isinstance(value.get("distance"), bool)
        )

    checks: dict[str, Callable[[str], bool]] = {
        "timestep_s": lambda t: number(t) and float(t) > 0,
        "log_every": lambda t: integer(t) and int(t) > 0,
        "plane_z": lambda t: t == "" or number(t),
        "static_potential_J": number,
        "steps": integer,
    }
    json_checks: dict[str, Callable[[Any], bool]] = {
        "spec": lambda v: isinstance(v, dict),
        "sweep": lambda v: isinstance(v, dict),
        "gravity": vector,
        "bodies": lambda v: isinstance(v, list) and all(body(b) for b in v),
        "ground": lambda v: isinstance(v, list) and all(surface(s) for s in v),
        "warnings": lambda v: isinstance(v, list) and all(isinstance(w, str) for w in v),
    }
    for key, ok in checks.items():
        if key in meta and not ok(meta[key]):
            return f"{key} = {meta[key][:40]!r} is not valid"
    for key, ok in json_checks.items():
        if key not in meta:
            continue
        try:
            valid = ok(json.loads(meta[key]))
        except ValueError:
            valid = False
        if not valid:
            return f"{key} is not valid JSON of the expected shape"
    return None


def _real(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)
