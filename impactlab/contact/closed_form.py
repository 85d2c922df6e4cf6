"""The linear spring-dashpot in continuous time: Schwager & Poeschel's closed form, the checks."""

from __future__ import annotations

import math
from collections.abc import Callable


class ContactModelError(ValueError):
    """A restitution target, contact geometry or timestep the contact model cannot deliver."""


RESTITUTION_FLOOR = math.exp(-2.0)
"""Lowest reachable e: the Schwager-Poeschel e at critical damping (zeta -> 1), exp(-2)."""


ZETA_MAX = 1.0


LIMITS = {
    "speed": (1e-4, 1e4, "m/s"),
    "timestep_s": (1e-9, 1.0, "s"),
    "radius_m": (1e-6, 1e3, "m"),
    "max_penetration_m": (1e-9, 1e3, "m"),
    "duration_s": (1e-9, 10.0, "s"),
    "gravity_mps2": (0.0, 1e4, "m/s^2"),
}
"""What the designer handles; outside, one clear error instead of overflowing arithmetic."""


def checked(name: str, value: object, key: str | None = None) -> float:
    """`value` as a positive number (>= 0 where LIMITS allows 0) within LIMITS[key or name].

    Raises:
        ContactModelError: not a number, not positive, or outside LIMITS.
    """
    lo, hi, unit = LIMITS[key or name]
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        x = math.nan
    if not math.isfinite(x) or x < 0.0 or (x == 0.0 and lo > 0.0):
        kind = "a positive number" if lo > 0.0 else "a number >= 0"
        raise ContactModelError(f"{name} must be {kind}, got {value!r}")
    if not lo <= x <= hi:
        raise ContactModelError(
            f"{name} = {x:g} {unit} is outside what the designer handles ({lo:g} .. {hi:g})"
        )
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


def contact_time_factor(zeta: float) -> float:
    """Return w0 * t_c, the contact duration in units of 1/w0 (contact ends at zero force).

    Args:
        zeta: damping ratio (>= 0).

    Returns:
        w0 * t_c (dimensionless): pi at zeta = 0, 2 at zeta = 1.
    """
    z = check_zeta(zeta)
    if z < 1.0:
        w = math.sqrt(1.0 - z * z)
        # atan2 joins the paper's two underdamped branches (zeta below and above 1/sqrt(2))
        return (math.pi - math.atan2(2.0 * z * w, w * w - z * z)) / w
    if z == 1.0:
        return 2.0
    g = math.sqrt(z * z - 1.0)
    return math.atanh(2.0 * z * g / (z * z + g * g)) / g


def restitution_closed_form(zeta: float) -> float:
    """Schwager-Poeschel restitution of the linear dashpot whose contact ends at zero force.

    ``e = exp(-beta t_c)`` with beta = zeta w0 and t_c from :func:`contact_time_factor`
    (underdamped branches as in the paper; zeta = 1 is the limit exp(-2); zeta > 1 is the
    overdamped continuation, outside the range :func:`contact_params` uses).

    Args:
        zeta: damping ratio (>= 0).

    Returns:
        e in (0, 1].
    """
    z = check_zeta(zeta)
    return math.exp(-z * contact_time_factor(z))


def zeta_for_restitution(e: float) -> float:
    """Invert :func:`restitution_closed_form` on 0 <= zeta <= 1 (continuous time).

    Args:
        e: target restitution, RESTITUTION_FLOOR <= e <= 1.

    Returns:
        The damping ratio zeta.

    Raises:
        ContactModelError: if e is not a number or outside [RESTITUTION_FLOOR, 1].
    """
    e = check_restitution(e)
    return bisect(lambda z: restitution_closed_form(z) - e, 0.0, ZETA_MAX)


def max_penetration_factor(zeta: float) -> float:
    """Return w0 * x_max / v_in for the continuous zero-gravity dashpot (1 at zeta = 0).

    The maximum is at t* = atan2(w, beta) / w, x_max = (v_in / w0) exp(-beta t*).
    """
    z = check_zeta(zeta)
    if z >= 1.0:
        if z == 1.0:
            return math.exp(-1.0)
        g = math.sqrt(z * z - 1.0)
        s1, s2 = -z + g, -z - g
        t = math.log(s2 / s1) / (s1 - s2)
        return (math.exp(s1 * t) - math.exp(s2 * t)) / (s1 - s2)
    w = math.sqrt(1.0 - z * z)
    return math.exp(-z * math.atan2(w, z) / w)
