"""Translate a target coefficient of restitution into MuJoCo contact parameters.

MuJoCo has no restitution parameter (google-deepmind/mujoco issue #2080). This module uses the
direct form of ``solref`` (``(-stiffness, -damping)``) with a constant impedance close to 1, for
which a MuJoCo contact is a linear spring-dashpot in the contact's normal coordinate, independent
of the masses::

    a_normal = -k * dist - b * dist_dot        while the contact force is positive

The Schwager & Poeschel closed form (Granular Matter 9, 2007) gives e(zeta) for that law with the
contact ending when the force vanishes; it is inverted for zeta and then corrected for MuJoCo's
time discretisation with a table (``restitution_table.json``) computed once by an exact numpy
emulation of ``mj_step`` for this contact (the emulation matches ``mj_step`` to 1e-14; the
tests check it). Regenerate the table with ``python -m impactlab.record.restitution``.

Stiffness rule of :func:`contact_params` (``w0 = sqrt(stiffness)``, ``v`` the impact speed):

1. ``duration_s`` given: w0 from the contact duration; else ``max_penetration_m`` given: w0 from
   that penetration at ``v``; else the softest w0 that keeps the worst-case penetration at ``v``
   below ``max_penetration_fraction * radius_m`` and ``g / (w0 v) <= GRAVITY_RATIO_MAX`` (pass
   ``gravity_mps2=0`` for zero-gravity scenes). The softest contact is the one with the most
   steps per contact.
2. The timestep must resolve that contact: ``w0 * timestep_s`` must not exceed what keeps the
   worst-case error (over where in a step the contact begins) within the budget, otherwise
   :class:`ContactModelError` names the steps per contact and the largest timestep that works.

Gravity (a body on a fixed surface): e is measured surface to surface, from the velocity in the
last state before the overlap to the one in the first state after it (as
``impactlab.analyze.bounces`` does). When the force lets go the ball is still inside the floor
(overlap about 2 zeta v_out / w0) and gravity slows it on the way out, which lowers that e by
about 2 zeta g / (w0 v) (0.02 for e = 0.2 at g / (w0 v) = 0.015). :func:`contact_params`
calibrates zeta for ``target - shift``, the shift computed for the design speed by a closed-form
evaluation of the same step emulation continued until the ball is back at the surface
(:func:`_impact_fast`, a few fixed-point iterations); :func:`surface_restitution` and
:func:`restitution_with_gravity` predict e at other speeds (lower below the design speed, higher
above it, by at most the shift).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

__all__ = [
    "GRAVITY_RATIO_MAX",
    "IMPEDANCE",
    "RESTITUTION_FLOOR",
    "RESTITUTION_TOLERANCE",
    "ContactModelError",
    "ContactParams",
    "check_timestep",
    "contact_params",
    "generate_table",
    "max_penetration_factor",
    "restitution_closed_form",
    "restitution_with_gravity",
    "surface_restitution",
    "zeta_for_restitution",
]

IMPEDANCE = 0.9999
"""solimp dmin = dmax: MuJoCo's largest impedance (mjMAXIMP). With the direct solref, MuJoCo
uses K = stiffness / d^2 and B = damping / d, so the contact acceleration is exactly
-stiffness * dist - damping * dist_dot + (1 - d) * a_free."""

SOLIMP: tuple[float, float, float, float, float] = (IMPEDANCE, IMPEDANCE, 0.001, 0.5, 2.0)
"""Constant impedance: with dmin = dmax, width, midpoint and power have no effect."""

RESTITUTION_TOLERANCE = 0.005
"""Accuracy promised for |e_measured - e_target| at the design point."""

_PHASE_BUDGET = 0.004
"""Part of the tolerance given to the timestep (worst case over contact-onset phase); the rest
covers table interpolation and the residual of the gravity calibration."""

GRAVITY_RATIO_MAX = 0.015
"""Default bound on g / (w0 * v_in) at the design speed. Gravity's shift of the surface-to-surface
e, about -2 zeta g / (w0 v), is calibrated out at the design speed; this bound keeps it (and so
the change of e with the impact speed) to about 0.02 at most."""

RESTITUTION_FLOOR = math.exp(-2.0)
"""Lowest reachable e: the Schwager-Poeschel e at critical damping (zeta -> 1), exp(-2)."""

_ZETA_MAX = 1.0
_TABLE_PATH = Path(__file__).with_name("restitution_table.json")


class ContactModelError(ValueError):
    """A restitution target, contact geometry or timestep the contact model cannot deliver."""


@dataclass(frozen=True)
class ContactParams:
    """MuJoCo contact parameters that deliver a target restitution.

    Attributes:
        solref: ``(-stiffness, -damping)``, MuJoCo's direct form.
        solimp: constant impedance ``(d, d, width, midpoint, power)``.
        stiffness: k in 1/s^2 (acceleration per metre of penetration; mass independent).
        damping: b in 1/s (acceleration per m/s of normal velocity).
        zeta: damping ratio b / (2 sqrt(k)), calibrated for ``timestep_s``.
        duration_s: predicted contact duration in s (independent of the impact speed).
        max_penetration_m: predicted worst-case penetration in m at ``impact_speed_mps``.
        restitution: the target e.
        impact_speed_mps: design impact speed in m/s.
        timestep_s: the timestep in s the calibration is for.
        gravity_mps2: gravity along the contact normal the calibration is for (0: none).
        gravity_shift: predicted change of e by gravity at the design speed (about
            -2 zeta g / (w0 v); 0 without gravity), calibrated out: zeta is chosen so that the
            zero-gravity e is ``restitution - gravity_shift``.
    """

    solref: tuple[float, float]
    solimp: tuple[float, float, float, float, float]
    stiffness: float
    damping: float
    zeta: float
    duration_s: float
    max_penetration_m: float
    restitution: float
    impact_speed_mps: float
    timestep_s: float
    gravity_mps2: float = 0.0
    gravity_shift: float = 0.0

    def mjcf_attributes(self) -> dict[str, str]:
        """Return ``{"solref": ..., "solimp": ...}`` as MJCF attribute strings (full precision)."""
        return {
            "solref": " ".join(repr(float(x)) for x in self.solref),
            "solimp": " ".join(repr(float(x)) for x in self.solimp),
        }


# --------------------------------------------------------------------------- closed forms


def _check_zeta(zeta: float) -> float:
    zeta = float(zeta)
    if not math.isfinite(zeta) or zeta < 0.0:
        raise ContactModelError(f"damping ratio zeta must be finite and >= 0, got {zeta!r}")
    return zeta


def contact_time_factor(zeta: float) -> float:
    """Return w0 * t_c, the contact duration in units of 1/w0 (contact ends at zero force).

    Args:
        zeta: damping ratio (>= 0).

    Returns:
        w0 * t_c (dimensionless): pi at zeta = 0, 2 at zeta = 1.
    """
    z = _check_zeta(zeta)
    if z == 0.0:
        return math.pi
    if z < 1.0:
        w = math.sqrt(1.0 - z * z)
        if z < math.sqrt(0.5):
            return (math.pi - math.atan(2.0 * z * w / (w * w - z * z))) / w
        if z * z - w * w == 0.0:
            return (math.pi / 2.0) / w
        return math.atan(2.0 * z * w / (z * z - w * w)) / w
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
    z = _check_zeta(zeta)
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
    e = _check_restitution(e)
    return _bisect(lambda z: restitution_closed_form(z) - e, 0.0, _ZETA_MAX)


def max_penetration_factor(zeta: float) -> float:
    """Return w0 * x_max / v_in for the continuous zero-gravity dashpot (1 at zeta = 0).

    The maximum is at t* = atan2(w, beta) / w, x_max = (v_in / w0) exp(-beta t*).
    """
    z = _check_zeta(zeta)
    if z >= 1.0:
        if z == 1.0:
            return math.exp(-1.0)
        g = math.sqrt(z * z - 1.0)
        s1, s2 = -z + g, -z - g
        t = math.log(s2 / s1) / (s1 - s2)
        return (math.exp(s1 * t) - math.exp(s2 * t)) / (s1 - s2)
    w = math.sqrt(1.0 - z * z)
    return math.exp(-z * math.atan2(w, z) / w)


def _check_restitution(e: float) -> float:
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


def _bisect(f, lo: float, hi: float, tol: float = 1e-13) -> float:
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


# --------------------------------------------------------------------------- mj_step emulation


def _emulate(
    zeta: np.ndarray,
    w0dt: float,
    phases: np.ndarray,
    gravity_ratio: float = 0.0,
    impedance: float = IMPEDANCE,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact emulation of mj_step (semi-implicit Euler) for one impact, in units w0 = v_in = 1.

    The first contact step starts at dist = -phase * w0dt (phase in (0, 1]) with velocity -1.
    Per step: aref = -(b u + k y) / d; the constraint is active iff dist < 0 and aref > a_free;
    then a = d aref + (1 - d) a_free, else a = a_free = -gravity_ratio.

    Args:
        zeta: damping ratios, shape (nz,).
        w0dt: w0 * timestep.
        phases: contact-onset phases, shape (nph,).
        gravity_ratio: g / (w0 v_in).
        impedance: solimp d.

    Returns:
        e (nz x nph): velocity after the last force step / v_in;
        penetration (nz x nph): max overlap * w0 / v_in;
        steps (nz x nph): number of steps with a positive force.
    """
    zeta = np.asarray(zeta, float)[:, None]
    ph = np.asarray(phases, float)[None, :]
    shape = np.broadcast_shapes(zeta.shape, ph.shape)
    y = np.broadcast_to(-ph * w0dt, shape).copy()
    u = -np.ones(shape)
    b = np.broadcast_to(2.0 * zeta, shape)
    a_free = -gravity_ratio
    u_out = np.zeros(shape)
    pen = np.zeros(shape)
    steps = np.zeros(shape, dtype=np.int64)
    started = np.zeros(shape, bool)
    done = np.zeros(shape, bool)
    for _ in range(int(40.0 / w0dt) + 100):
        aref = -(b * u + y) / impedance
        force = (y < 0.0) & (aref > a_free) & ~done
        done |= started & ~force
        if done.all():
            break
        a = np.where(force, impedance * aref + (1.0 - impedance) * a_free, a_free)
        pen = np.maximum(pen, np.where(force, -y, 0.0))
        u = u + w0dt * a
        y = y + w0dt * u
        pen = np.maximum(pen, np.where(force, -y, 0.0))
        started |= force
        steps += force
        u_out = np.where(force, u, u_out)
    return u_out, pen, steps


def _emulate_surface(
    zeta: float,
    w0dt: float,
    phases: np.ndarray,
    gravity_ratio: float | np.ndarray = 0.0,
    impedance: float = IMPEDANCE,
    t_max: float = 40.0,
) -> tuple[np.ndarray, np.ndarray]:
    """mj_step emulation of one impact, continued until the ball is back at the surface.

    Units w0 = 1 and v_in = 1, v_in being the speed in the last state before the overlap (what
    the analysis stage takes): the first overlapping state has velocity -(1 + w0dt * gr) and
    dist = -phase * w0dt * (1 + w0dt * gr), phase in (0, 1]. Each step applies MuJoCo's rule
    (the constraint pushes while dist < 0 and aref > a_free), also after the force has let go,
    until the first state with dist >= 0.

    Args:
        zeta: damping ratio.
        w0dt: w0 * timestep.
        phases: contact-onset phases, shape (n,).
        gravity_ratio: g / (w0 v_in), scalar or shape (n,).
        impedance: solimp d.
        t_max: give up (e = 0: the ball does not leave) after this time, in 1 / w0.

    Returns:
        (release, surface), each shape (n,): the velocity after the last step with a positive
        force, and the velocity in the first state back at the surface (0 if it never leaves).
    """
    h = float(w0dt)
    gr = np.broadcast_to(np.asarray(gravity_ratio, float), np.shape(phases)).copy()
    u = -(1.0 + h * gr)
    y = np.asarray(phases, float) * h * u
    d = impedance
    release = np.full(y.shape, np.nan)
    surface = np.zeros(y.shape)
    released = np.zeros(y.shape, bool)
    done = np.zeros(y.shape, bool)
    for _ in range(int(t_max / h) + 100):
        aref = -(2.0 * zeta * u + y) / d
        force = (y < 0.0) & (aref > -gr)
        let_go = ~force & ~released
        release = np.where(let_go, u, release)
        released |= let_go
        u = u + h * np.where(force, d * aref + (1.0 - d) * -gr, -gr)
        y = y + h * u
        left = ~done & (y >= 0.0)
        surface = np.where(left, np.maximum(u, 0.0), surface)
        done |= left
        if done.all():
            break
    release = np.where(released, release, u)
    return release, surface


def _step_powers(m: np.ndarray, n: int) -> np.ndarray:
    """M^0 .. M^(n-1) of a 2 x 2 matrix, shape (n, 2, 2), by doubling (log2 n matmuls)."""
    p = np.empty((n, 2, 2))
    p[0] = np.eye(2)
    k = 1
    while k < n:
        mk = p[k - 1] @ m
        j = min(k, n - k)
        p[k : k + j] = p[:j] @ mk
        k += j
    return p


def _impact_fast(
    zeta: float,
    w0dt: float,
    phases: np.ndarray,
    gravity_ratio: np.ndarray,
    impedance: float = IMPEDANCE,
) -> tuple[np.ndarray, np.ndarray]:
    """The result of :func:`_emulate_surface`, without stepping (same rounding level).

    While the constraint pushes, one step is affine in (dist, velocity), so the states of the
    force phase are powers of the step matrix; after the force lets go the ball flies freely
    and the first state at the surface follows from a quadratic. Columns whose force phase does
    not end within 3.6 / w0, or whose constraint would grip again on the way out (very low
    impact speed), are emulated step by step.
    """
    h = float(w0dt)
    ph = np.asarray(phases, float)
    gr = np.broadcast_to(np.asarray(gravity_ratio, float), ph.shape)
    d = impedance
    b = 2.0 * zeta
    u0 = -(1.0 + h * gr)
    x0 = np.stack([ph * h * u0, u0])  # (2, n): dist, velocity
    m = np.array([[1.0 - h * h, h * (1.0 - b * h)], [-h, 1.0 - b * h]])
    c = -(1.0 - d) * h * np.stack([h * gr, gr])  # (2, n)
    fixed = np.linalg.solve(np.eye(2) - m, c)
    n = int(3.6 / h) + 3
    x = np.einsum("kij,jn->kin", _step_powers(m, n), x0 - fixed) + fixed[None]
    y, u = x[:, 0], x[:, 1]
    force = (y < 0.0) & (-(b * u + y) / d > -gr)
    force[0] = True
    r = np.argmin(force, axis=0)
    cols = np.arange(ph.size)
    ok = ~force[r, cols]
    yr, ur = y[r, cols], u[r, cols]
    # free flight: u_k = ur - k h gr, y_k = yr + h k ur - h^2 gr k (k + 1) / 2; first y_k >= 0
    a2 = 0.5 * h * h * gr
    b2 = h * ur - a2
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(
            gr > 0.0,
            (b2 - np.sqrt(np.maximum(b2 * b2 + 4.0 * a2 * yr, 0.0))) / (2.0 * a2),
            -yr / (h * ur),
        )
    k = np.maximum(np.ceil(np.nan_to_num(k, nan=0.0, posinf=0.0, neginf=0.0)), 0.0)

    def dist(k: np.ndarray) -> np.ndarray:
        return yr + h * k * ur - a2 * k * (k + 1.0)

    k = np.where((k > 0.0) & (dist(k - 1.0) >= 0.0), k - 1.0, k)
    k = np.where(dist(k) < 0.0, k + 1.0, k)
    # the constraint stays off on the way out if it is off at the last state inside (the
    # margin y + 2 zeta u - d gr is concave in k): otherwise step through it
    last = np.maximum(k - 1.0, 0.0)
    grip = (k > 0.0) & (dist(last) + b * (ur - last * h * gr) < d * gr)
    ok &= (ur > 0.0) & ~grip & (dist(k) >= 0.0)
    release, surface = ur, np.maximum(ur - k * h * gr, 0.0)
    if not ok.all():
        bad = ~ok
        release, surface = release.copy(), surface.copy()
        release[bad], surface[bad] = _emulate_surface(zeta, h, ph[bad], gr[bad], impedance)
    return release, surface


_SHIFT_PHASES = (np.arange(16) + 0.5) / 16
_SHIFT_W0DT_MIN = 0.01


def _gravity_shift(zeta: float, w0dt: float, gravity_ratio: float) -> float:
    """Gravity's change of the surface-to-surface e at one impact speed (mean over phases).

    ``mean(e_surface at g / (w0 v)) - mean(e at zero gravity)`` by :func:`_impact_fast` over 16
    contact-onset phases; about -2 zeta g / (w0 v): after the force lets go the ball is still
    inside the floor (overlap about 2 zeta v_out / w0) and gravity slows it on the way out.
    Steps finer than w0 dt = 0.01 are evaluated at 0.01 (the shift changes by O(w0 dt g / (w0 v)),
    below 1e-4 there).
    """
    if gravity_ratio <= 0.0:
        return 0.0
    h = max(float(w0dt), _SHIFT_W0DT_MIN)
    n = _SHIFT_PHASES.size
    gr = np.concatenate([np.zeros(n), np.full(n, float(gravity_ratio))])
    _, surface = _impact_fast(zeta, h, np.tile(_SHIFT_PHASES, 2), gr)
    return float(surface[n:].mean() - surface[:n].mean())


# --------------------------------------------------------------------------- calibration table

_TABLE_ZETA = np.linspace(0.0, 1.0, 41) ** 1.5
_TABLE_W0DT = np.geomspace(0.002, 0.3, 31)
_TABLE_PHASES = np.linspace(0.0, 1.0, 257)[1:]


def generate_table() -> dict:
    """Compute the discretisation table over (zeta, w0 * dt) with the mj_step emulation.

    For each node, over 256 contact-onset phases: ``delta`` = midrange of e minus the closed
    form, ``half`` = half the range of e (worst-case phase error once delta is calibrated out),
    ``pen`` = worst-case max penetration * w0 / v_in.

    Returns:
        A JSON-serialisable dict (arrays shaped len(zeta) x len(w0dt)).
    """
    nz, nw = len(_TABLE_ZETA), len(_TABLE_W0DT)
    delta, half, pen = (np.zeros((nz, nw)) for _ in range(3))
    closed = np.array([restitution_closed_form(z) for z in _TABLE_ZETA])
    for j, wh in enumerate(_TABLE_W0DT):
        e, p, _ = _emulate(_TABLE_ZETA, float(wh), _TABLE_PHASES)
        delta[:, j] = 0.5 * (e.max(1) + e.min(1)) - closed
        half[:, j] = 0.5 * (e.max(1) - e.min(1))
        pen[:, j] = p.max(1)
    return {
        "generated_by": "python -m impactlab.record.restitution",
        "description": (
            "MuJoCo linear spring-dashpot contact (direct solref, solimp d = "
            f"{IMPEDANCE}), zero gravity, semi-implicit Euler; over {len(_TABLE_PHASES)} "
            "contact-onset phases: delta = midrange(e) - closed form, half = range(e) / 2, "
            "pen = max penetration * w0 / v_in"
        ),
        "impedance": IMPEDANCE,
        "zeta": _TABLE_ZETA.tolist(),
        "w0dt": _TABLE_W0DT.tolist(),
        "delta": np.round(delta, 10).tolist(),
        "half": np.round(half, 10).tolist(),
        "pen": np.round(pen, 10).tolist(),
    }


@dataclass(frozen=True)
class _Table:
    zeta: np.ndarray
    log_w0dt: np.ndarray
    closed: np.ndarray
    delta: np.ndarray
    half: np.ndarray
    pen: np.ndarray

    def columns(self, w0dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Interpolate (delta, half, pen) over the zeta grid at w0dt (linear in log w0dt).

        Below the table, delta and half are scaled by w0dt / w0dt_min (both ~ w0dt).
        """
        lw = math.log(w0dt)
        if lw <= self.log_w0dt[0]:
            s = w0dt / math.exp(self.log_w0dt[0])
            p_cont = np.array([max_penetration_factor(z) for z in self.zeta])
            return (
                self.delta[:, 0] * s,
                self.half[:, 0] * s,
                p_cont + (self.pen[:, 0] - p_cont) * s,
            )
        j = int(np.searchsorted(self.log_w0dt, lw)) - 1
        j = min(max(j, 0), len(self.log_w0dt) - 2)
        t = (lw - self.log_w0dt[j]) / (self.log_w0dt[j + 1] - self.log_w0dt[j])
        t = min(t, 1.0)
        return tuple(
            (1.0 - t) * a[:, j] + t * a[:, j + 1] for a in (self.delta, self.half, self.pen)
        )

    @property
    def w0dt_max(self) -> float:
        return float(math.exp(self.log_w0dt[-1]))


@functools.cache
def _table() -> _Table:
    raw = json.loads(_TABLE_PATH.read_text())
    zeta = np.asarray(raw["zeta"], float)
    return _Table(
        zeta=zeta,
        log_w0dt=np.log(np.asarray(raw["w0dt"], float)),
        closed=np.array([restitution_closed_form(z) for z in zeta]),
        delta=np.asarray(raw["delta"], float),
        half=np.asarray(raw["half"], float),
        pen=np.asarray(raw["pen"], float),
    )


def _discrete(zeta: float, w0dt: float) -> tuple[float, float, float]:
    """Return (midrange e, worst phase error, worst penetration factor) at (zeta, w0dt)."""
    tab = _table()
    delta, half, pen = tab.columns(w0dt)
    return (
        restitution_closed_form(zeta) + float(np.interp(zeta, tab.zeta, delta)),
        float(np.interp(zeta, tab.zeta, half)),
        float(np.interp(zeta, tab.zeta, pen)),
    )


def _calibrated_zeta(e: float, w0dt: float) -> float:
    """zeta whose phase-midrange discrete e equals e at w0dt."""
    tab = _table()
    delta, _, _ = tab.columns(w0dt)
    return _bisect(
        lambda z: restitution_closed_form(z) + float(np.interp(z, tab.zeta, delta)) - e,
        0.0,
        _ZETA_MAX,
    )


def _w0dt_max(e: float) -> float:
    """Largest w0 * dt (within the table) at which the calibrated worst-case error fits."""
    tab = _table()
    prev_wh, prev_err = None, None
    for lw in tab.log_w0dt:
        wh = float(math.exp(lw))
        _, half, _ = _discrete(_calibrated_zeta(e, wh), wh)
        if half > _PHASE_BUDGET:
            if prev_wh is None:
                return wh * _PHASE_BUDGET / half
            t = (_PHASE_BUDGET - prev_err) / (half - prev_err)
            return math.exp(math.log(prev_wh) + t * (lw - math.log(prev_wh)))
        prev_wh, prev_err = wh, half
    return tab.w0dt_max


def _shifted_target(e: float, shift: float, gravity_ratio: float) -> float:
    """The zero-gravity e to calibrate for so that gravity's shift brings it to e."""
    target = e - shift
    if not RESTITUTION_FLOOR <= target <= 1.0:
        raise ContactModelError(
            f"e = {e:g} cannot be reached under gravity with g / (w0 v) = {gravity_ratio:.3g}: "
            f"gravity changes e by {shift:+.3g} at the design speed; use a stiffer contact"
        )
    return target


# --------------------------------------------------------------------------- public API


def _positive(name: str, value: float | None) -> float:
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ContactModelError(f"{name} must be a positive number, got {value!r}") from None
    if not math.isfinite(x) or x <= 0.0:
        raise ContactModelError(f"{name} must be a positive number, got {value!r}")
    return x


def contact_params(
    restitution: float,
    *,
    radius_m: float,
    impact_speed_mps: float,
    timestep_s: float,
    duration_s: float | None = None,
    max_penetration_m: float | None = None,
    max_penetration_fraction: float = 0.02,
    gravity_mps2: float = 9.81,
    allow_coarse: bool = False,
) -> ContactParams:
    """Contact parameters (solref, solimp) that make MuJoCo deliver a restitution.

    Args:
        restitution: target e, RESTITUTION_FLOOR <= e <= 1.
        radius_m: smaller radius of the two bodies in m (sets the default penetration bound).
        impact_speed_mps: design normal impact speed in m/s.
        timestep_s: simulation timestep in s (the calibration is for this timestep).
        duration_s: contact duration in s; overrides the penetration rule.
        max_penetration_m: max penetration in m at the impact speed; overrides the default.
        max_penetration_fraction: default penetration bound as a fraction of radius_m.
        gravity_mps2: gravity along the contact normal in m/s^2 for a body on a fixed surface
            (0 for zero-gravity scenes and for two free bodies, whose relative motion gravity
            does not change). Gravity lowers the e measured surface to surface by about
            2 zeta g / (w0 v); the calibration compensates that at the design speed (see
            :func:`surface_restitution`), and the default stiffness keeps
            g / (w0 v) <= GRAVITY_RATIO_MAX.
        allow_coarse: warn instead of raising if the timestep does not resolve the contact.

    Returns:
        The calibrated :class:`ContactParams`.

    Raises:
        ContactModelError: unreachable restitution, invalid input, both duration_s and
            max_penetration_m given, or a timestep too coarse for the contact.
    """
    e = _check_restitution(restitution)
    radius = _positive("radius_m", radius_m)
    v = _positive("impact_speed_mps", impact_speed_mps)
    dt = _positive("timestep_s", timestep_s)
    g = float(gravity_mps2)
    if not math.isfinite(g) or g < 0.0:
        raise ContactModelError(f"gravity_mps2 must be >= 0, got {gravity_mps2!r}")
    if duration_s is not None and max_penetration_m is not None:
        raise ContactModelError("give duration_s or max_penetration_m, not both")

    wh_cap = _table().w0dt_max

    def zeta_at(w0: float, shift: float) -> float:
        return _calibrated_zeta(_shifted_target(e, shift, g / (w0 * v)), min(w0 * dt, wh_cap))

    def shift_at(zeta: float, w0: float) -> float:
        return _gravity_shift(zeta, min(w0 * dt, wh_cap), g / (w0 * v)) if g > 0.0 else 0.0

    # zeta is calibrated for the zero-gravity e, target - shift, where shift is gravity's change
    # of the surface-to-surface e at the design speed; shift depends on zeta and w0, w0 (through
    # the penetration or duration rule) on zeta: iterate both, then converge the shift at w0.
    shift = 0.0
    if duration_s is not None:
        tc = _positive("duration_s", duration_s)
        w0 = contact_time_factor(zeta_for_restitution(e)) / tc
        for _ in range(4):
            z = zeta_at(w0, shift)
            w0 = contact_time_factor(z) / tc
            shift = shift_at(z, w0)
    else:
        if max_penetration_m is not None:
            bound = _positive("max_penetration_m", max_penetration_m)
            w0_gravity = 0.0
        else:
            fraction = _positive("max_penetration_fraction", max_penetration_fraction)
            bound = fraction * radius
            w0_gravity = g / (GRAVITY_RATIO_MAX * v)
        w0 = v * max_penetration_factor(zeta_for_restitution(e)) / bound
        for _ in range(6):
            z = zeta_at(w0, shift)
            pen = _discrete(z, min(w0 * dt, wh_cap))[2]
            w0 = max(v * pen / (bound * 0.995), w0_gravity)
            shift = shift_at(z, w0)
    # the shift is piecewise constant in zeta (the step in which the ball is back at the
    # surface jumps by one for one phase: h g / (w0 v) / 16, up to ~5e-5), so the iteration may
    # end in a tiny cycle: stop at 1e-4
    for _ in range(12):
        zeta = zeta_at(w0, shift)
        new_shift = shift_at(zeta, w0)
        step, shift = abs(new_shift - shift), new_shift
        if step <= 1e-4:
            break
    if step > 1e-3:
        raise ContactModelError(
            f"cannot calibrate e = {e:g} under gravity {g:g} m/s^2 at {v:g} m/s with stiffness "
            f"{w0 * w0:.4g} (g / (w0 v) = {g / (w0 * v):.3g}): use a stiffer contact"
        )
    zeta = zeta_at(w0, shift)

    w0dt = w0 * dt
    _, _, pen = _discrete(zeta, min(w0dt, wh_cap))
    k = w0 * w0
    b = 2.0 * zeta * w0
    params = ContactParams(
        solref=(-k, -b),
        solimp=SOLIMP,
        stiffness=k,
        damping=b,
        zeta=zeta,
        duration_s=contact_time_factor(zeta) / w0,
        max_penetration_m=v * pen / w0,
        restitution=e,
        impact_speed_mps=v,
        timestep_s=dt,
        gravity_mps2=g,
        gravity_shift=shift,
    )
    check_timestep(params, dt, allow_coarse=allow_coarse)
    return params


def check_timestep(params: ContactParams, timestep_s: float, *, allow_coarse: bool = False) -> int:
    """Check that a timestep resolves the contact well enough for the restitution tolerance.

    The worst-case error (over where in a step the contact begins) is predicted from the
    calibration table: |midrange e(zeta, w0 dt) + gravity shift - target| + half range. It must
    be within RESTITUTION_TOLERANCE - 0.001.

    Args:
        params: parameters from :func:`contact_params`.
        timestep_s: simulation timestep in s.
        allow_coarse: warn (UserWarning) instead of raising.

    Returns:
        Steps per contact, floor(duration_s / timestep_s).

    Raises:
        ContactModelError: the timestep is too coarse (message names steps per contact, the
            steps needed and the largest timestep that would work).
    """
    dt = _positive("timestep_s", timestep_s)
    w0 = math.sqrt(params.stiffness)
    w0dt = w0 * dt
    steps = int(params.duration_s / dt)
    e = params.restitution
    mid, half, _ = _discrete(params.zeta, min(w0dt, _table().w0dt_max))
    err = abs(mid + params.gravity_shift - e) + half
    too_coarse = w0dt > _table().w0dt_max * (1.0 + 1e-9)
    if err <= _PHASE_BUDGET + 1e-6 and not too_coarse:
        return steps
    wh_max = _w0dt_max(e)
    dt_max = wh_max / w0
    steps_needed = math.ceil(params.duration_s / dt_max)
    if too_coarse or w0dt > wh_max * (1.0 + 1e-6):
        msg = (
            f"timestep {dt:.3g} s gives {steps} steps per contact (w0*dt = {w0dt:.3g}); "
            f"e = {e:.4g} within {RESTITUTION_TOLERANCE} needs >= {steps_needed} steps, i.e. "
            f"timestep <= {dt_max:.3g} s for stiffness {params.stiffness:.4g} "
            f"(or a softer contact: larger max penetration / longer duration)"
        )
    else:
        msg = (
            f"contact parameters were calibrated for timestep {params.timestep_s:.3g} s, not "
            f"{dt:.3g} s: predicted worst-case error {err:.4f} > {_PHASE_BUDGET}; call "
            f"contact_params with timestep_s={dt:.6g}"
        )
    if allow_coarse:
        warnings.warn(msg, UserWarning, stacklevel=2)
        return steps
    raise ContactModelError(msg)


def restitution_with_gravity(
    params: ContactParams,
    *,
    impact_speed_mps: float,
    gravity_mps2: float,
    contact_law: Literal["mujoco", "dashpot"] = "mujoco",
    timestep_s: float | None = None,
    at: Literal["surface", "release"] = "surface",
) -> float:
    """Predict e of a ball hitting a floor with gravity, at any impact speed.

    By default (``at="surface"``) e is measured surface to surface, as the analysis stage and
    the bounce apex see it: -v_out / v_in with v_in the velocity when the ball reaches the
    surface and v_out when it is back at the surface. ``at="release"`` gives the velocity when
    the contact force lets go instead; the ball is then still inside the floor and gravity
    slows it by about 2 zeta g / (w0 v_in) on the way out.

    Laws (y = signed distance, negative in contact; k, b from params):

    - ``"mujoco"``: what MuJoCo does. The constraint targets y'' = -k y - b y' and cancels
      gravity while it pushes; it lets go when -(k y + b y') < -g or at y = 0, and may grip
      again on the way out (very low speeds).
    - ``"dashpot"``: the physical dashpot on a rigid floor (arXiv 2204.10917):
      y'' = -k y - b y' - g while the force -(k y + b y') is positive.

    Args:
        params: contact parameters.
        impact_speed_mps: normal impact speed in m/s.
        gravity_mps2: gravity in m/s^2 (>= 0).
        contact_law: ``"mujoco"`` or ``"dashpot"``.
        timestep_s: for ``"mujoco"`` only: emulate mj_step with this timestep and return the
            mean over 64 contact-onset phases; None integrates the continuous law.
        at: ``"surface"`` or ``"release"`` (see above).

    Returns:
        e; 0 if the ball does not leave the floor.
    """
    v = _positive("impact_speed_mps", impact_speed_mps)
    g = float(gravity_mps2)
    if not math.isfinite(g) or g < 0.0:
        raise ContactModelError(f"gravity_mps2 must be >= 0, got {gravity_mps2!r}")
    if contact_law not in ("mujoco", "dashpot"):
        raise ContactModelError(f"unknown contact_law {contact_law!r}")
    if at not in ("surface", "release"):
        raise ContactModelError(f"at must be 'surface' or 'release', got {at!r}")
    w0 = math.sqrt(params.stiffness)
    zeta = params.damping / (2.0 * w0)
    gr = g / (w0 * v)
    if timestep_s is not None:
        if contact_law != "mujoco":
            raise ContactModelError("timestep_s is only supported for contact_law='mujoco'")
        dt = _positive("timestep_s", timestep_s)
        if at == "surface":
            return surface_restitution(
                params, impact_speed_mps=v, gravity_mps2=g, timestep_s=dt, phases=64
            )
        phases = (np.arange(64) + 0.5) / 64
        e, _, _ = _emulate(np.array([zeta]), w0 * dt, phases, gr)
        return float(e.mean())
    if at == "surface":
        return _surface_speed_continuous(zeta, gr, contact_law)
    # mujoco: y itself is homogeneous; released when y + 2 zeta y' >= g / (w0 v).
    # dashpot: z = y + g / w0^2 is homogeneous; released when z + 2 zeta z' >= g / (w0 v).
    z0 = 0.0 if contact_law == "mujoco" else gr
    return _release_speed(zeta, z0, gr)


def surface_restitution(
    params: ContactParams,
    *,
    impact_speed_mps: float | Sequence[float],
    gravity_mps2: float,
    timestep_s: float,
    phases: int = 64,
) -> float | np.ndarray:
    """e of a ball on a floor measured surface to surface, by the mj_step emulation.

    Emulates MuJoCo's step for this contact and continues after the force lets go until the
    ball is back at the surface: e = (velocity in the first state after the overlap) / (speed
    in the last state before it), what the analysis stage measures. Mean over `phases`
    contact-onset phases; 0 when the ball does not leave within 40 / w0.

    While the ball is still inside the floor after the force lets go (overlap about
    2 zeta v_out / w0), gravity slows it for about 2 zeta / w0 s, so e_surface = e_release -
    2 zeta g / (w0 v) to first order; :func:`contact_params` compensates that at its design
    speed, so e_surface equals the target there and is lower at lower speeds.

    Args:
        params: contact parameters.
        impact_speed_mps: impact speed(s) in m/s.
        gravity_mps2: gravity along the normal in m/s^2 (>= 0).
        timestep_s: simulation timestep in s.
        phases: number of contact-onset phases averaged.

    Returns:
        e, a float for one speed or an array (one per speed).
    """
    speeds = np.atleast_1d(np.asarray(impact_speed_mps, float))
    if not np.all(speeds > 0.0):
        raise ContactModelError(f"impact speeds must be positive, got {impact_speed_mps!r}")
    g = float(gravity_mps2)
    if not math.isfinite(g) or g < 0.0:
        raise ContactModelError(f"gravity_mps2 must be >= 0, got {gravity_mps2!r}")
    w0 = math.sqrt(params.stiffness)
    zeta = params.damping / (2.0 * w0)
    ph = (np.arange(phases) + 0.5) / phases
    gr = np.repeat(g / (w0 * speeds), phases)
    _, surface = _emulate_surface(
        zeta, w0 * _positive("timestep_s", timestep_s), np.tile(ph, speeds.size), gr
    )
    e = surface.reshape(speeds.size, phases).mean(axis=1)
    return float(e[0]) if np.ndim(impact_speed_mps) == 0 else e


def _surface_speed_continuous(
    zeta: float, gravity_ratio: float, law: str, h: float = 1e-3, t_max: float = 40.0
) -> float:
    """Continuous-time surface-to-surface e (w0 = v_in = 1) by RK4, from y = 0, y' = -1.

    The acceleration inside the floor (y < 0, or y = 0 moving in) is, for ``"mujoco"``,
    max(-g, d aref + (1 - d)(-g)) with aref = -(y + 2 zeta y') / d (MuJoCo's rule), and for
    ``"dashpot"`` -g + max(0, -(y + 2 zeta y')); outside it is -g. Returns the velocity where
    y crosses 0 again (linear interpolation), 0 if that does not happen within t_max.
    """
    gr, b, d = gravity_ratio, 2.0 * zeta, IMPEDANCE
    mujoco_law = law == "mujoco"

    def acc(y: float, u: float) -> float:
        if y > 0.0 or (y == 0.0 and u >= 0.0):
            return -gr
        if mujoco_law:
            aref = -(b * u + y) / d
            return d * aref - (1.0 - d) * gr if aref > -gr else -gr
        return max(-(b * u + y), 0.0) - gr

    y, u = 0.0, -1.0
    for _ in range(int(t_max / h)):
        k1y, k1u = u, acc(y, u)
        k2y, k2u = u + 0.5 * h * k1u, acc(y + 0.5 * h * k1y, u + 0.5 * h * k1u)
        k3y, k3u = u + 0.5 * h * k2u, acc(y + 0.5 * h * k2y, u + 0.5 * h * k2u)
        k4y, k4u = u + h * k3u, acc(y + h * k3y, u + h * k3u)
        y1 = y + h / 6.0 * (k1y + 2.0 * k2y + 2.0 * k3y + k4y)
        u1 = u + h / 6.0 * (k1u + 2.0 * k2u + 2.0 * k3u + k4u)
        if y1 >= 0.0 and y < 0.0:
            f = y / (y - y1)
            return max(u + f * (u1 - u), 0.0)
        y, u = y1, u1
    return 0.0


def _release_speed(zeta: float, z0: float, threshold: float) -> float:
    """Release speed of z'' = -z - 2 zeta z' (w0 = v_in = 1) from (z0, -1).

    Released at the first t > 0 with z + 2 zeta z' >= threshold or z >= z0 (back at the
    surface); returns max(z', 0) there (0 if the contact never releases within 20 / w0).
    """
    lam = np.roots([1.0, 2.0 * zeta, 1.0]).astype(complex)
    if abs(lam[0] - lam[1]) < 1e-9:  # critical damping: perturb
        lam = lam + np.array([1e-7, -1e-7])
    vmat = np.array([[1.0, 1.0], [lam[0], lam[1]]])
    c = np.linalg.solve(vmat, np.array([z0, -1.0], complex))
    t = np.linspace(0.0, 20.0, 200_001)
    ex = np.exp(np.outer(t, lam))
    z = (ex @ c).real
    zd = (ex @ (c * lam)).real
    # released when the floor no longer pushes or the ball is back at the surface (y = z - z0)
    s = np.maximum(z + 2.0 * zeta * zd - threshold, z - z0)
    idx = np.flatnonzero(s[1:] >= 0.0)
    if idx.size == 0:
        return 0.0
    i = int(idx[0])
    f = s[i] / (s[i] - s[i + 1]) if s[i + 1] != s[i] else 1.0
    return max(float(zd[i] + f * (zd[i + 1] - zd[i])), 0.0)


# --------------------------------------------------------------------------- entry point


def main(argv: Sequence[str] | None = None) -> int:
    """Regenerate (or check) the committed calibration table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=_TABLE_PATH, help="output JSON path")
    parser.add_argument(
        "--check", action="store_true", help="fail if the committed table is out of date"
    )
    args = parser.parse_args(argv)
    text = json.dumps(generate_table(), indent=1) + "\n"
    if args.check:
        current = args.out.read_text() if args.out.exists() else ""
        if current != text:
            print(f"{args.out} is out of date; run python -m impactlab.record.restitution")
            return 1
        print(f"{args.out} is up to date")
        return 0
    args.out.write_text(text)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


# --------------------------------------------------------------------------- measurement


@dataclass(frozen=True)
class ImpactMeasurement:
    """One impact measured in MuJoCo (normal components; ball 1 moves towards ball 2 / floor).

    Measured surface to surface, as the analysis stage does (``impactlab.analyze.bounces``).

    Attributes:
        restitution: -(relative normal velocity after) / (relative normal velocity before).
        v_before_mps: body velocities (z for the floor, x for two balls) in the last state
            before the bodies overlap, shape (nbody,).
        v_after_mps: body velocities in the first state after the overlap, (nbody,).
        max_penetration_m: largest overlap in m.
        steps_in_contact: number of steps with a positive contact force.
    """

    restitution: float
    v_before_mps: tuple[float, ...]
    v_after_mps: tuple[float, ...]
    max_penetration_m: float
    steps_in_contact: int


def ball_plane_mjcf(
    params: ContactParams, *, radius_m: float, mass_kg: float, gravity_mps2: float
) -> str:
    """Inline MJCF: a frictionless (condim 1) ball on a plane, the pair set by ``<pair>``."""
    a = params.mjcf_attributes()
    return f"""<mujoco><option timestep="{params.timestep_s!r}" gravity="0 0 {-gravity_mps2!r}"/>
<worldbody><geom name="floor" type="plane" size="10 10 1" condim="1"/>
<body name="ball" pos="0 0 1"><freejoint/>
<geom name="ball" type="sphere" size="{radius_m!r}" mass="{mass_kg!r}" condim="1"/></body>
</worldbody><contact><pair geom1="floor" geom2="ball" condim="1" solref="{a["solref"]}"
solimp="{a["solimp"]}"/></contact></mujoco>"""


def ball_ball_mjcf(
    params: ContactParams, *, radius_m: tuple[float, float], mass_kg: tuple[float, float]
) -> str:
    """Inline MJCF: two frictionless balls on the x axis in zero gravity, ``<pair>`` contact."""
    a = params.mjcf_attributes()
    return f"""<mujoco><option timestep="{params.timestep_s!r}" gravity="0 0 0"/>
<worldbody>
<body name="b1" pos="-1 0 0"><freejoint/>
<geom name="b1" type="sphere" size="{radius_m[0]!r}" mass="{mass_kg[0]!r}" condim="1"/></body>
<body name="b2" pos="1 0 0"><freejoint/>
<geom name="b2" type="sphere" size="{radius_m[1]!r}" mass="{mass_kg[1]!r}" condim="1"/></body>
</worldbody><contact><pair geom1="b1" geom2="b2" condim="1" solref="{a["solref"]}"
solimp="{a["solimp"]}"/></contact></mujoco>"""


def _measure(model, data, velocities, overlap, max_steps: int) -> ImpactMeasurement:
    """Step until the bodies overlap and part again; velocities just outside the overlap.

    As the analysis stage does: v_before is the state before the first overlapping one,
    v_after the first state without overlap after it (surface to surface).
    """
    import mujoco

    v_prev = v_before = v_after = None
    pen, steps = 0.0, 0
    for _ in range(max_steps):
        inside = overlap(data) > 0.0
        v_now = velocities(data)
        if inside:
            if v_before is None:
                if v_prev is None:
                    raise ContactModelError("the bodies overlap in the initial state")
                v_before = v_prev
            pen = max(pen, overlap(data))
        elif v_before is not None:
            v_after = v_now
            break
        v_prev = v_now
        mujoco.mj_step(model, data)
        steps += data.nefc > 0 and bool(np.any(data.efc_force[: data.nefc] > 0.0))
    if v_before is None or v_after is None:
        raise ContactModelError("no complete contact within the simulated steps")
    rel_in = v_before[-1] - v_before[0]
    rel_out = v_after[-1] - v_after[0]
    return ImpactMeasurement(
        restitution=-rel_out / rel_in,
        v_before_mps=tuple(map(float, v_before)),
        v_after_mps=tuple(map(float, v_after)),
        max_penetration_m=pen,
        steps_in_contact=steps,
    )


def measure_ball_plane(
    params: ContactParams,
    *,
    radius_m: float,
    mass_kg: float,
    impact_speed_mps: float,
    gravity_mps2: float = 9.81,
    gap_m: float | None = None,
) -> ImpactMeasurement:
    """Drop a ball onto a plane in MuJoCo and measure e from the velocities around the contact.

    The ball starts ``gap_m`` above the plane (default 2.37 steps of travel) moving down at
    the speed that makes it arrive at ``impact_speed_mps``.
    """
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        ball_plane_mjcf(params, radius_m=radius_m, mass_kg=mass_kg, gravity_mps2=gravity_mps2)
    )
    data = mujoco.MjData(model)
    gap = 2.37 * impact_speed_mps * params.timestep_s if gap_m is None else gap_m
    data.qpos[2] = radius_m + gap
    data.qvel[2] = -math.sqrt(max(impact_speed_mps**2 - 2.0 * gravity_mps2 * gap, 0.0))
    max_steps = int(20.0 * params.duration_s / params.timestep_s) + 10 * int(
        gap / (impact_speed_mps * params.timestep_s) + 10
    )
    meas = _measure(
        model,
        data,
        lambda d: np.array([0.0, -d.qvel[2]]),  # (floor, ball) velocities towards the floor
        lambda d: radius_m - d.qpos[2],
        max_steps,
    )
    return ImpactMeasurement(
        restitution=meas.restitution,
        v_before_mps=(-meas.v_before_mps[1],),
        v_after_mps=(-meas.v_after_mps[1],),
        max_penetration_m=meas.max_penetration_m,
        steps_in_contact=meas.steps_in_contact,
    )


def measure_ball_ball(
    params: ContactParams,
    *,
    radius_m: tuple[float, float],
    mass_kg: tuple[float, float],
    velocity_mps: tuple[float, float],
    gap_m: float | None = None,
) -> ImpactMeasurement:
    """Collide two balls head-on along x in zero gravity and measure e and both velocities.

    Ball 1 (left) moves at velocity_mps[0], ball 2 (right) at velocity_mps[1] (closing speed
    v1 - v2 > 0); they start ``gap_m`` apart (default 2.37 steps of closing travel).
    """
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        ball_ball_mjcf(params, radius_m=radius_m, mass_kg=mass_kg)
    )
    data = mujoco.MjData(model)
    closing = velocity_mps[0] - velocity_mps[1]
    if not closing > 0.0:
        raise ContactModelError(f"balls must approach (v1 - v2 > 0), got {velocity_mps}")
    gap = 2.37 * closing * params.timestep_s if gap_m is None else gap_m
    data.qpos[0] = -radius_m[0] - gap / 2.0
    data.qpos[7] = radius_m[1] + gap / 2.0
    data.qvel[0], data.qvel[6] = velocity_mps
    max_steps = int(20.0 * params.duration_s / params.timestep_s) + int(
        10 * gap / (closing * params.timestep_s) + 100
    )
    meas = _measure(
        model,
        data,
        lambda d: np.array([d.qvel[6], d.qvel[0]]),  # ordered so that out/in is the closing rate
        lambda d: radius_m[0] + radius_m[1] - (d.qpos[7] - d.qpos[0]),
        max_steps,
    )
    return ImpactMeasurement(
        restitution=meas.restitution,
        v_before_mps=(meas.v_before_mps[1], meas.v_before_mps[0]),
        v_after_mps=(meas.v_after_mps[1], meas.v_after_mps[0]),
        max_penetration_m=meas.max_penetration_m,
        steps_in_contact=meas.steps_in_contact,
    )
