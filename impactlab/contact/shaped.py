"""A contact whose impedance rises with penetration: MuJoCo's d(r), one impact emulated."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from impactlab.contact.emulation import Acceleration, advance, scheme_of

MIN_IMPEDANCE, MAX_IMPEDANCE = 0.0001, 0.9999
"""MuJoCo's clamp of the impedance (mjMINIMP, mjMAXIMP)."""


def impedance(solimp: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """MuJoCo's impedance d(r) at penetration depths (m), solimp = (dmin, dmax, width,
    midpoint, power) along the last axis of length 5 broadcastable with `depth` (the
    engine's getimpedance: a power law to the midpoint, its mirror image beyond, flat
    outside the width; clamped to MIN_IMPEDANCE..MAX_IMPEDANCE)."""
    return _impedance_of(solimp)(depth)


def _impedance_of(solimp: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """:func:`impedance` with the shape's constants computed once."""
    dmin, dmax, width, mid, power = (solimp[..., i] for i in range(5))
    with np.errstate(divide="ignore", over="ignore"):
        below = 1.0 / mid ** (power - 1.0)
        above = 1.0 / (1.0 - mid) ** (power - 1.0)
    rise = dmax - dmin

    def d(depth: np.ndarray) -> np.ndarray:
        x = np.minimum(depth / width, 1.0)  # depth >= 0
        low = x <= mid
        t = np.where(low, x, 1.0 - x) ** power
        y = np.where(low, below * t, 1.0 - above * t)
        clamped: np.ndarray = np.clip(dmin + y * rise, MIN_IMPEDANCE, MAX_IMPEDANCE)
        return clamped

    return d


def contact_rule(solref: np.ndarray, solimp: np.ndarray, gravity_mps2: float) -> Acceleration:
    """MuJoCo's normal acceleration of a ball on a plane with a direct-form solref (-k, -b):
    K = k / dmax^2, B = b / dmax, aref = -B v - K d(r) dist; the constraint pushes while
    dist < 0 and aref > a0 = -g, and the acceleration is then d aref + (1 - d) a0 (a single
    frictionless contact, whose diagonal approximation is exact)."""
    g = float(gravity_mps2)
    dmax = np.clip(solimp[..., 1], MIN_IMPEDANCE, MAX_IMPEDANCE)
    stiff, damp = -solref[..., 0] / dmax**2, -solref[..., 1] / dmax
    impedance_at = _impedance_of(solimp)

    def acceleration(y: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = impedance_at(np.maximum(-y, 0.0))
        aref = -damp * u - stiff * d * y
        force = (y < 0.0) & (aref > -g)
        return np.where(force, d * aref - (1.0 - d) * g, -g), force

    return acceleration


@dataclass(frozen=True)
class Impacts:
    """Single impacts emulated, one per element of the broadcast shape.

    Attributes:
        e: -v_out / v_in as the recorder measures them (0: the ball did not leave).
        penetration_m: the largest overlap of a state.
        contact_s: time from the first state in contact to the first state out of it.
    """

    e: np.ndarray
    penetration_m: np.ndarray
    contact_s: np.ndarray


def emulate(
    solref: np.ndarray,
    solimp: np.ndarray,
    speed_mps: np.ndarray,
    phases: np.ndarray,
    *,
    timestep_s: float,
    gravity_mps2: float,
    integrator: str,
    max_time_s: float,
) -> Impacts:
    """mj_step emulation of one impact of a ball on a plane with a direct-form solref
    ``(-k, -b)`` and any solimp (last axis of length 2 and 5), at recorded impact speeds
    (m/s) and contact-onset phases in (0, 1], all broadcast together.

    The acceleration is :func:`contact_rule`'s. The last state before the overlap lies
    ``1 - phase`` free-flight steps above the surface; the recorder's impact speed is the
    velocity of the first state in contact (for RK4 that of the state before, whose later
    stages meet the surface already). An impact still in contact after `max_time_s` gets
    e = 0 and no contact time.
    """
    scheme = scheme_of(integrator)
    dt, g = float(timestep_s), float(gravity_mps2)
    v = np.asarray(speed_mps, float)
    ph = np.asarray(phases, float)
    shape = np.broadcast_shapes(solref.shape[:-1], solimp.shape[:-1], v.shape, ph.shape)
    refs = np.broadcast_to(solref, (*shape, 2)).reshape(-1, 2)
    imps = np.broadcast_to(solimp, (*shape, 5)).reshape(-1, 5)
    v = np.broadcast_to(v, shape).ravel()
    ph = np.broadcast_to(ph, shape).ravel()
    if scheme == "euler":  # the first state in contact has fallen one more step
        v_pre, travel = v - dt * g, dt * v
    else:
        v_pre, travel = v, dt * (v + 0.5 * dt * g)
    y, u = (1.0 - ph) * travel, -v_pre
    out, pen = np.zeros(v.size), np.zeros(v.size)
    first, last = np.zeros(v.size), np.full(v.size, np.nan)
    active = np.arange(v.size)  # the impacts not yet back at the surface
    deepest, entered = np.zeros(v.size), np.zeros(v.size)  # of the active ones
    rule = contact_rule(refs, imps, g)
    for n in range(1, int(max_time_s / dt) + 3):
        y, u, _ = advance(y, u, dt, rule, scheme)
        inside = y < 0.0
        deepest = np.maximum(deepest, -y)
        if entered.all():
            left = ~inside
        else:
            entered = np.where(inside & (entered == 0), n, entered)
            left = ~inside & (entered > 0)
        if left.any():
            gone = active[left]
            out[gone], last[gone] = np.maximum(u[left], 0.0), n
            pen[gone], first[gone] = deepest[left], entered[left]
            keep = ~left
            active, y, u = active[keep], y[keep], u[keep]
            deepest, entered = deepest[keep], entered[keep]
            if active.size == 0:
                break
            rule = contact_rule(refs[active], imps[active], g)
    pen[active], first[active] = deepest, entered
    e = np.where(np.isnan(last), 0.0, out / v)
    return Impacts(e.reshape(shape), pen.reshape(shape), ((last - first) * dt).reshape(shape))
