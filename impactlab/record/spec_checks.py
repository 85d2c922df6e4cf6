"""Type and range checks of spec fields; each failure is a `SpecError` naming the field."""

from __future__ import annotations

import math
from typing import Any

from impactlab.errors import SpecError


class FieldChecks:
    """Type and range checks that raise `SpecError` naming the field."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, field: str, problem: str) -> SpecError:
        return SpecError(self.source, field, problem)

    def number(self, value: Any, field: str, *, min_exclusive: float | None = None) -> float:
        if value is None:
            raise self.fail(field, "is required")
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(field, f"must be a number, got {value!r}")
        if not math.isfinite(value):
            raise self.fail(field, f"must be finite, got {value!r}")
        if min_exclusive is not None and value <= min_exclusive:
            raise self.fail(field, f"must be > {min_exclusive:g}, got {value!r}")
        return float(value)

    def optional(self, value: Any, field: str, *, positive: bool = False) -> float | None:
        if value is None:
            return None
        return self.number(value, field, min_exclusive=0.0 if positive else None)

    def integer(self, value: Any, field: str, min_value: int | None = None) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(field, f"must be an integer, got {value!r}")
        if min_value is not None and value < min_value:
            raise self.fail(field, f"must be >= {min_value}, got {value!r}")
        return value

    def boolean(self, value: Any, field: str) -> bool:
        if not isinstance(value, bool):
            raise self.fail(field, f"must be true or false, got {value!r}")
        return value

    def choice(self, value: Any, field: str, choices: tuple[str, ...]) -> str:
        if value not in choices:
            raise self.fail(field, f"must be one of {', '.join(choices)}, got {value!r}")
        return value

    def name(self, value: Any, field: str) -> str:
        if not isinstance(value, str) or not value or not value.replace("_", "a").isalnum():
            raise self.fail(field, f"must be a name of letters, digits and _, got {value!r}")
        return value

    def vector(
        self,
        value: Any,
        field: str,
        length: int | tuple[int, ...],
        *,
        min_value: float | None = None,
        max_value: float | None = None,
    ) -> tuple[float, ...]:
        lengths = (length,) if isinstance(length, int) else length
        if value is None:
            raise self.fail(field, "is required")
        if not isinstance(value, list | tuple) or len(value) not in lengths:
            want = " or ".join(str(n) for n in lengths)
            raise self.fail(field, f"must be a list of {want} numbers, got {value!r}")
        out = tuple(self.number(x, field) for x in value)
        if min_value is not None and any(x < min_value for x in out):
            raise self.fail(field, f"values must be >= {min_value:g}, got {list(value)}")
        if max_value is not None and any(x > max_value for x in out):
            raise self.fail(field, f"values must be <= {max_value:g}, got {list(value)}")
        return out
