"""Gravity's effect on e for a body on a fixed surface, measured as the recorder measures it."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from impactlab.contact.closed_form import ContactModelError, checked
from impactlab.contact.emulation import emulate_surface, scheme_of, speed_in
from impactlab.contact.fast import impact_fast
from impactlab.contact.params import ContactParams

_SHIFT_PHASES = (np.arange(16) + 0.5) / 16


_SHIFT_W0DT_MIN = 0.01


def gravity_shift(
    zeta: float,
    w0dt: float,
    gravity_ratio: Sequence[float] | np.ndarray,
    integrator: str = "Euler",
) -> np.ndarray:
    """Gravity's change of e at impact speeds (mean over phases), one per ratio.

    ``mean(e at g / (w0 v)) - mean(e at zero gravity)`` by :func:`impact_fast` over 16
    contact-onset phases, e = -v_out / v_in as the recorder measures them; about
    -2 zeta g / (w0 v). Steps finer than w0 dt = 0.01 are evaluated at 0.01 (the shift
    changes by O(w0 dt g / (w0 v)), below 1e-4 there).

    Args:
        zeta: damping ratio.
        w0dt: w0 * timestep.
        gravity_ratio: g / (w0 v), one per impact speed.
        integrator: MuJoCo's integrator name.
    """
    ratios = np.atleast_1d(np.asarray(gravity_ratio, float))
    h = max(float(w0dt), _SHIFT_W0DT_MIN)
    n = _SHIFT_PHASES.size
    gr = np.concatenate([np.zeros(n), np.repeat(np.maximum(ratios, 0.0), n)])
    phases = np.tile(_SHIFT_PHASES, ratios.size + 1)
    _, surface = impact_fast(zeta, h, phases, gr, integrator=integrator)
    e = surface / speed_in(h, gr, scheme_of(integrator))
    means = e.reshape(ratios.size + 1, n).mean(axis=1)
    shift: np.ndarray = np.where(ratios > 0.0, means[1:] - means[0], 0.0)
    return shift


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
