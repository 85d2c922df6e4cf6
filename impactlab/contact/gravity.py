"""Gravity's effect on e for a body on a fixed surface, measured surface to surface.

After the force lets go the ball is still inside the floor (overlap about 2 zeta v_out / w0)
and gravity slows it on the way out, which lowers e by about 2 zeta g / (w0 v).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal, overload

import numpy as np

from impactlab.contact.checks import ContactModelError, positive
from impactlab.contact.emulation import IMPEDANCE, emulate_impact, emulate_surface, scheme_of
from impactlab.contact.fast import impact_fast
from impactlab.contact.params import ContactParams

_SHIFT_PHASES = (np.arange(16) + 0.5) / 16


_SHIFT_W0DT_MIN = 0.01


@overload
def gravity_shift(
    zeta: float, w0dt: float, gravity_ratio: float, integrator: str = "Euler"
) -> float: ...
@overload
def gravity_shift(
    zeta: float, w0dt: float, gravity_ratio: Sequence[float] | np.ndarray, integrator: str = "Euler"
) -> np.ndarray: ...
def gravity_shift(
    zeta: float,
    w0dt: float,
    gravity_ratio: float | Sequence[float] | np.ndarray,
    integrator: str = "Euler",
) -> float | np.ndarray:
    """Gravity's change of the surface-to-surface e at impact speeds (mean over phases).

    ``mean(e_surface at g / (w0 v)) - mean(e at zero gravity)`` by :func:`impact_fast` over 16
    contact-onset phases; about -2 zeta g / (w0 v): after the force lets go the ball is still
    inside the floor (overlap about 2 zeta v_out / w0) and gravity slows it on the way out.
    Steps finer than w0 dt = 0.01 are evaluated at 0.01 (the shift changes by O(w0 dt g / (w0 v)),
    below 1e-4 there).

    Args:
        zeta: damping ratio.
        w0dt: w0 * timestep.
        gravity_ratio: g / (w0 v), one value or several (one per impact speed).
        integrator: MuJoCo's integrator name.

    Returns:
        The shift, a float for one ratio or an array (one per ratio).
    """
    ratios = np.atleast_1d(np.asarray(gravity_ratio, float))
    h = max(float(w0dt), _SHIFT_W0DT_MIN)
    n = _SHIFT_PHASES.size
    gr = np.concatenate([np.zeros(n), np.repeat(np.maximum(ratios, 0.0), n)])
    phases = np.tile(_SHIFT_PHASES, ratios.size + 1)
    _, surface = impact_fast(zeta, h, phases, gr, integrator=integrator)
    means = surface.reshape(ratios.size + 1, n).mean(axis=1)
    shift = np.where(ratios > 0.0, means[1:] - means[0], 0.0)
    return float(shift[0]) if np.ndim(gravity_ratio) == 0 else shift


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
    v = positive("impact_speed_mps", impact_speed_mps)
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
        dt = positive("timestep_s", timestep_s)
        if at == "surface":
            return surface_restitution(
                params, impact_speed_mps=v, gravity_mps2=g, timestep_s=dt, phases=64
            )
        phases = (np.arange(64) + 0.5) / 64
        if scheme_of(params.integrator) == "euler":
            e, _, _ = emulate_impact(np.array([zeta]), w0 * dt, phases, gr)
        else:
            e, _, _ = emulate_surface(zeta, w0 * dt, phases, gr, integrator=params.integrator)
        return float(e.mean())
    if at == "surface":
        return _surface_speed_continuous(zeta, gr, contact_law)
    # mujoco: y itself is homogeneous; released when y + 2 zeta y' >= g / (w0 v).
    # dashpot: z = y + g / w0^2 is homogeneous; released when z + 2 zeta z' >= g / (w0 v).
    z0 = 0.0 if contact_law == "mujoco" else gr
    return _release_speed(zeta, z0, gr)


@overload
def surface_restitution(
    params: ContactParams,
    *,
    impact_speed_mps: float,
    gravity_mps2: float,
    timestep_s: float,
    phases: int = 64,
) -> float: ...
@overload
def surface_restitution(
    params: ContactParams,
    *,
    impact_speed_mps: Sequence[float] | np.ndarray,
    gravity_mps2: float,
    timestep_s: float,
    phases: int = 64,
) -> np.ndarray: ...
def surface_restitution(
    params: ContactParams,
    *,
    impact_speed_mps: float | Sequence[float] | np.ndarray,
    gravity_mps2: float,
    timestep_s: float,
    phases: int = 64,
) -> float | np.ndarray:
    """e of a ball on a floor measured surface to surface, by the mj_step emulation.

    Emulates MuJoCo's step (with the integrator of ``params``) for this contact and continues
    after the force lets go until the ball is back at the surface: e = (velocity in the first
    state after the overlap) / (speed in the last state before it), what the analysis stage
    measures. Mean over `phases` contact-onset phases; 0 when the ball does not leave within
    40 / w0.

    While the ball is still inside the floor after the force lets go (overlap about
    2 zeta v_out / w0), gravity slows it for about 2 zeta / w0 s, so e_surface = e_release -
    2 zeta g / (w0 v) to first order; :func:`contact_params` centres that over its speed range,
    so e_surface is within the tolerance of the target there and lower at lower speeds.

    Args:
        params: contact parameters.
        impact_speed_mps: impact speed(s) in m/s.
        gravity_mps2: gravity along the normal in m/s^2 (>= 0).
        timestep_s: simulation timestep in s.
        phases: number of contact-onset phases averaged.

    Returns:
        e, a float for one speed or an array (one per speed).
    """
    mean, _, _ = restitution_spread(
        params,
        impact_speed_mps=impact_speed_mps,
        gravity_mps2=gravity_mps2,
        timestep_s=timestep_s,
        phases=phases,
    )
    return float(mean[0]) if np.ndim(impact_speed_mps) == 0 else mean


def restitution_spread(
    params: ContactParams,
    *,
    impact_speed_mps: float | Sequence[float] | np.ndarray,
    gravity_mps2: float,
    timestep_s: float,
    phases: int = 64,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Surface-to-surface e at impact speeds: mean, lowest and highest over contact-onset phases.

    The same emulation as :func:`surface_restitution`; the lowest and highest are what single
    impacts at that speed may give, depending on where in a step the contact begins.

    Returns:
        (mean, lowest, highest), each one value per speed.
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
    gr = (g / (w0 * speeds))[:, None]
    _, surface, _ = emulate_surface(
        zeta,
        w0 * positive("timestep_s", timestep_s),
        ph[None, :],
        gr,
        integrator=params.integrator,
    )
    return surface.mean(axis=1), surface.min(axis=1), surface.max(axis=1)


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
