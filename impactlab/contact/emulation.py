"""Exact numpy emulations of `mj_step` for one impact of this contact, per integrator."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from impactlab.contact.closed_form import ContactModelError, checked
from impactlab.contact.params import ContactParams

IMPEDANCE = 0.9999
"""solimp dmin = dmax: MuJoCo's largest impedance (mjMAXIMP). With the direct solref, MuJoCo
uses K = stiffness / d^2 and B = damping / d, so the contact acceleration is exactly
-stiffness * dist - damping * dist_dot + (1 - d) * a_free."""


SOLIMP: tuple[float, float, float, float, float] = (IMPEDANCE, IMPEDANCE, 0.001, 0.5, 2.0)
"""Constant impedance: with dmin = dmax, width, midpoint and power have no effect."""


SCHEMES = {"Euler": "euler", "implicit": "euler", "implicitfast": "euler", "RK4": "rk4"}
"""MuJoCo's integrators and how each one steps this contact (see the module docstring)."""


def scheme_of(integrator: str) -> str:
    """The stepping scheme ("euler" or "rk4") of a MuJoCo integrator name.

    Raises:
        ContactModelError: an integrator MuJoCo does not have.
    """
    try:
        return SCHEMES[integrator]
    except (KeyError, TypeError):
        raise ContactModelError(
            f"integrator must be one of {', '.join(SCHEMES)}, got {integrator!r}"
        ) from None


def _acceleration(
    y: np.ndarray, u: np.ndarray, b: np.ndarray | float, gr: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's contact rule: (acceleration, force on) at states (y, u)."""
    d = IMPEDANCE
    aref = -(b * u + y) / d
    force = (y < 0.0) & (aref > -gr)
    return np.where(force, d * aref + (1.0 - d) * -gr, -gr), force


def step(
    y: np.ndarray,
    u: np.ndarray,
    h: float,
    b: np.ndarray | float,
    gr: np.ndarray | float,
    scheme: str,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One step of MuJoCo's integrator for this contact (units w0 = v_in = 1).

    Args:
        y, u: signed distance and normal velocity (arrays, broadcastable).
        h: w0 * timestep.
        b: 2 zeta, an array broadcastable with them or a scalar.
        gr: g / (w0 v_in) (gravity towards the surface), likewise.
        scheme: "euler" or "rk4" (:func:`scheme_of`).

    Returns:
        (y, u, force): the next state, and whether the constraint pushed in some evaluation
        of the step (one for Euler, four stages for RK4).
    """
    return advance(y, u, h, lambda y, u: _acceleration(y, u, b, gr), scheme)


Acceleration = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
"""(distance, normal velocity) -> (acceleration, whether the constraint pushes)."""


def advance(
    y: np.ndarray, u: np.ndarray, h: float, acceleration: Acceleration, scheme: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One step of MuJoCo's integrator ("euler" or "rk4") of a contact's acceleration rule,
    evaluated at every stage: (y, u, whether the constraint pushed at some stage)."""
    if scheme == "euler":
        a, f = acceleration(y, u)
        u = u + h * a
        return y + h * u, u, f
    a1, f1 = acceleration(y, u)
    y2, u2 = y + 0.5 * h * u, u + 0.5 * h * a1
    a2, f2 = acceleration(y2, u2)
    y3, u3 = y + 0.5 * h * u2, u + 0.5 * h * a2
    a3, f3 = acceleration(y3, u3)
    y4, u4 = y + h * u3, u + h * a3
    a4, f4 = acceleration(y4, u4)
    y_new = y + h / 6.0 * (u + 2.0 * u2 + 2.0 * u3 + u4)
    u_new = u + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return y_new, u_new, f1 | f2 | f3 | f4


def free_step_travel(h: float, gr: np.ndarray, scheme: str) -> np.ndarray:
    """Distance one free-flight step covers towards the surface from velocity -1 (w0 = 1)."""
    return h * (1.0 + h * gr) if scheme == "euler" else h * (1.0 + 0.5 * h * gr)


def speed_in(h: float, gr: np.ndarray | float, scheme: str) -> np.ndarray | float:
    """The impact speed as the recorder takes it (before any contact force acted), in units
    of the speed in the last state before the overlap (w0 = 1): Euler's first state in
    contact has fallen one more step (1 + h gr); RK4's is that state, since the later stages
    of its step already meet the surface (1). Divide the emulation's velocities by it."""
    return 1.0 + h * np.asarray(gr) if scheme == "euler" else 1.0


def emulate_surface(
    zeta: float | np.ndarray,
    w0dt: float,
    phases: np.ndarray,
    gravity_ratio: float | np.ndarray = 0.0,
    integrator: str = "Euler",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """mj_step emulation of one impact, continued until the ball is back at the surface.

    Units w0 = 1 and the speed in the last state before the overlap = 1 (`speed_in` turns
    them into the recorder's). That state is ``(1 - phase)`` free-flight steps above the
    surface, phase in (0, 1]. Each step applies MuJoCo's rule (the constraint pushes while
    dist < 0 and aref > a_free, at every stage of the integrator), also after the force has let
    go, until the first state with dist >= 0.

    Args:
        zeta: damping ratio, scalar or broadcastable with phases (e.g. shape (nz, 1)).
        w0dt: w0 * timestep.
        phases: contact-onset phases.
        gravity_ratio: g / (w0 v_in), scalar or broadcastable with phases.
        integrator: MuJoCo's integrator name (:data:`SCHEMES`).

    Returns:
        (release, surface, penetration), each of the broadcast shape: the velocity when the
        force first lets go, the velocity in the first state back at the surface (0 if it
        never leaves), and the largest overlap of a state * w0 / v_in.
    """
    scheme = scheme_of(integrator)
    h = float(w0dt)
    b = 2.0 * np.asarray(zeta, float)
    ph = np.asarray(phases, float)
    gr = np.asarray(gravity_ratio, float)
    shape = np.broadcast_shapes(b.shape, ph.shape, gr.shape)
    y = np.broadcast_to((1.0 - ph) * free_step_travel(h, gr, scheme), shape).copy()
    u = -np.ones(shape)
    release = np.full(shape, np.nan)
    surface = np.zeros(shape)
    pen = np.zeros(shape)
    pushed = np.zeros(shape, bool)
    released = np.zeros(shape, bool)
    entered = np.zeros(shape, bool)
    done = np.zeros(shape, bool)
    weightless = not np.any(gr)
    for _ in range(int(40.0 / h) + 100):  # 0: the ball does not leave within 40 / w0
        y_new, u_new, any_force = step(y, u, h, b, gr, scheme)
        let_go = pushed & ~any_force & ~released & ~done
        release = np.where(let_go, u, release)
        released |= let_go
        pushed |= any_force
        y, u = y_new, u_new
        entered |= y < 0.0
        pen = np.where(entered & ~done, np.maximum(pen, -y), pen)
        left = entered & ~done & (y >= 0.0)
        surface = np.where(left, np.maximum(u, 0.0), surface)
        release = np.where(left & ~released, u, release)  # pushed until it left
        released |= left
        done |= left
        if done.all():
            break
        if weightless and released.all():  # free flight at constant speed from here on
            surface = np.where(done, surface, np.maximum(u, 0.0))
            break
    release = np.where(released, release, u)
    return release, surface, pen


def restitution_spread(
    params: ContactParams,
    *,
    impact_speed_mps: float | Sequence[float] | np.ndarray,
    gravity_mps2: float,
    timestep_s: float,
    phases: int = 64,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """e at impact speeds by the mj_step emulation: mean, lowest and highest over phases.

    Emulates MuJoCo's step (with the integrator of ``params``) for this contact and continues
    after the force lets go until the ball is back at the surface: e = -v_out / v_in as the
    recorder measures them, for `phases` contact-onset phases; the lowest and highest are
    what single impacts at that speed may give, depending on where in a step the contact
    begins. 0 when the ball does not leave within 40 / w0.

    Returns:
        (mean, lowest, highest), each one value per speed.

    Raises:
        ContactModelError: a speed is not positive, or gravity negative or not a number.
    """
    speeds = np.atleast_1d(np.asarray(impact_speed_mps, float))
    if not np.all(speeds > 0.0):
        raise ContactModelError(f"impact speeds must be positive, got {impact_speed_mps!r}")
    g = checked("gravity_mps2", gravity_mps2)
    w0 = math.sqrt(params.stiffness)
    zeta = params.damping / (2.0 * w0)
    h = w0 * checked("timestep_s", timestep_s)
    ph = (np.arange(phases) + 0.5) / phases
    gr = (g / (w0 * speeds))[:, None]
    _, surface, _ = emulate_surface(zeta, h, ph[None, :], gr, integrator=params.integrator)
    e = surface / speed_in(h, gr, scheme_of(params.integrator))
    return e.mean(axis=1), e.min(axis=1), e.max(axis=1)
