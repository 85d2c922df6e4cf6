"""Input checks and the one error of the contact model."""

from __future__ import annotations

import math
from collections.abc import Callable


class ContactModelError(ValueError):
    """A restitution target, contact geometry or timestep the contact model cannot deliver."""


RESTITUTION_FLOOR = math.exp(-2.0)
"""Lowest reachable e: the Schwager-Poeschel e at critical damping (zeta -> 1), exp(-2)."""


ZETA_MAX = 1.0


def positive(name: str, value: float | None) -> float:
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ContactModelError(f"{name} must be a positive number, got {value!r}") from None
    if not math.isfinite(x) or x <= 0.0:
        raise ContactModelError(f"{name} must be a positive number, got {value!r}")
    return x


def check_zeta(zeta: float) -> float:
    zeta = float(zeta)
    if not math.isfinite(zeta) or zeta < 0.0:
        raise ContactModelError(f"damping ratio zeta must be finite and >= 0, got {zeta!r}")
    return zeta


def check_restitution(e: float) -> float:
    try:
        e = float(e)
    except (TypeError, ValueError):
        raise ContactModelError(
            f"restitution must be a number in [{RESTITUTION_FLOOR:.4f}, 1], got {e!r}"
        ) from None
    if not math.isfinite(e) or e > 1.0 or e < RESTITUTION_FLOOR:
        raise ContactModelError(
            f"restitution {e!r} cannot be reached: the linear spring-dashpot contact reaches "
            f"e in [{RESTITUTION_FLOOR:.4f}, 1] (floor = exp(-2) at critical damping, "
            "Schwager & Poeschel 2007)"
        )
    return e


def bisect(f: Callable[[float], float], lo: float, hi: float, tol: float = 1e-13) -> float:
    flo = f(lo)
    if flo == 0.0:
        return lo
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        fm = f(mid)
        if (fm > 0.0) == (flo > 0.0):
            lo, flo = mid, fm
        else:
            hi = mid
        if hi - lo < tol:
            break
    return 0.5 * (lo + hi)
