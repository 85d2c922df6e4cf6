"""Analytic formulas the measurements are compared against (numbers or polars expressions).

See shared physics notes: free flight, apex heights and the 1D collision with restitution e.
"""

from __future__ import annotations

from typing import TypeVar

X = TypeVar("X")


def collision_after(m1: X, m2: X, v1: X, v2: X, e: X | float) -> tuple[X, X]:
    """(v1', v2') of a 1D collision with restitution e: masses in kg, velocities in m/s along
    the line of centres (numbers, arrays or polars expressions)."""
    p = m1 * v1 + m2 * v2  # type: ignore[operator]
    total = m1 + m2  # type: ignore[operator]
    return (p + m2 * e * (v2 - v1)) / total, (p + m1 * e * (v1 - v2)) / total  # type: ignore[operator]
