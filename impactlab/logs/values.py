"""Parsing a metadata value: the one error type and the primitives every declared key uses."""

from __future__ import annotations

import json
import math
from typing import Any


class Invalid(ValueError):
    """A metadata value that does not hold; the message says why."""


def quote(value: Any) -> str:
    """A value as a problem names it: its text (JSON for non-text), cut to 40 characters."""
    text = value if isinstance(value, str) else json.dumps(value)
    return repr(text if len(text) <= 40 else text[:37] + "...")


def json_value(value: str) -> Any:
    """The JSON document of a stored string.

    Raises:
        Invalid: it is not valid JSON (or nested too deep to parse).
    """
    try:
        return json.loads(value)
    except (ValueError, RecursionError):
        raise Invalid(f"{quote(value)} is not valid JSON") from None


def number(value: str, low: float, high: float) -> float:
    """A stored number in [low, high].

    Raises:
        Invalid: it is not a number, not finite, or out of range.
    """
    try:
        parsed = float(value)
    except (TypeError, ValueError):
        raise Invalid(f"{quote(value)} is not a number") from None
    if not math.isfinite(parsed) or not low <= parsed <= high:
        raise Invalid(f"{quote(value)} is out of range")
    return parsed


def real(value: Any, low: float, high: float) -> bool:
    """Whether a parsed JSON value is a finite number (not a bool) in [low, high]."""
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(value)
        and low <= value <= high
    )
