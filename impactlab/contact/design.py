"""The designer: a target restitution over a range of impact speeds -> MuJoCo contact parameters.

MuJoCo has no restitution parameter (google-deepmind/mujoco issue #2080). This module uses the
direct form of ``solref`` (``(-stiffness, -damping)``) with a constant impedance close to 1, for
which a MuJoCo contact is a linear spring-dashpot in the contact's normal coordinate, independent
of the masses::

    a_normal = -k * dist - b * dist_dot        while the contact force is positive

The Schwager & Poeschel closed form (Granular Matter 9, 2007) gives e(zeta) for that law with the
contact ending when the force vanishes; it is inverted for zeta and then corrected for MuJoCo's
time discretisation with a table per integrator (``restitution_table*.json``) computed once by
an exact numpy emulation of ``mj_step`` for this contact (the tests check it against MuJoCo).

Without gravity e does not depend on the impact speed. With gravity (a ball on a fixed surface)
the e measured surface to surface (as ``impactlab.analyze.bounces`` does) is lower than the
zero-gravity e by about ``2 zeta g / (w0 v)``: after the force lets go the ball is still inside
the floor and gravity slows it on the way out. Over a range of impact speeds [v_lo, v_hi] that
shift changes by ``2 zeta g / w0 (1 / v_lo - 1 / v_hi)``. The designer centres it across the
range (zeta is calibrated for ``target - (shift(v_lo) + shift(v_hi)) / 2``) and picks the
stiffness so that the remaining half spread stays within ``SPREAD_BUDGET``.

Stiffness rule of :func:`contact_params` (``w0 = sqrt(stiffness)``):

1. ``duration_s`` given: w0 from the contact duration. Otherwise the softest w0 that keeps the
   worst-case penetration at ``v_hi`` below the bound (``max_penetration_m``, default
   ``max_penetration_fraction * radius_m``) and gravity's half spread over the range below
   ``SPREAD_BUDGET``. The softest contact has the most steps per contact.
2. The timestep must resolve that contact: the predicted worst case (phase error from the
   table, plus the half spread) must stay within ``PHASE_BUDGET``; otherwise
   :class:`ContactModelError` names the steps per contact and the largest timestep that works.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from impactlab.contact.checks import (
    RESTITUTION_FLOOR,
    ContactModelError,
    check_restitution,
    positive,
)
from impactlab.contact.closed_form import (
    contact_time_factor,
    max_penetration_factor,
    zeta_for_restitution,
)
from impactlab.contact.emulation import SOLIMP, scheme_of
from impactlab.contact.gravity import gravity_shift
from impactlab.contact.params import ContactParams
from impactlab.contact.table import PHASE_BUDGET, calibrated_zeta, discrete, table

RESTITUTION_TOLERANCE = 0.005
"""Accuracy promised for |e_measured - e_target| at every impact speed in the contact's range."""


SPREAD_BUDGET = 0.0015
"""Default bound on gravity's half spread of e over the speed range: the default stiffness is
at least the one that keeps e(v_lo) and e(v_hi) within this of the target (on average over
step phases). The rest of ``PHASE_BUDGET`` goes to the phase error, so the timestep needed
depends on how wide the range is."""


@dataclass(frozen=True)
class Evaluation:
    """One stiffness evaluated: calibrated zeta and the predicted errors (units of e)."""

    w0: float
    zeta: float
    shift: float  # centre of gravity's shift over the range, calibrated out
    spread: float  # half the change of e by gravity across the range
    phase: float  # worst-case phase error at this w0 * dt
    pen: float  # worst-case penetration factor w0 x_max / v_in
    w0dt: float

    @property
    def error(self) -> float:
        """Predicted worst |e - target| over the range and over step phases."""
        return self.phase + self.spread


def speed_range(
    speed_range_mps: Sequence[float] | None, impact_speed_mps: float | None
) -> tuple[float, float]:
    """(v_lo, v_hi) from a range or a single impact speed (a range of one speed).

    Raises:
        ContactModelError: neither or both given, or not 0 < v_lo <= v_hi.
    """
    if (speed_range_mps is None) == (impact_speed_mps is None):
        raise ContactModelError("give speed_range_mps = (v_lo, v_hi) or impact_speed_mps")
    if impact_speed_mps is not None:
        v = positive("impact_speed_mps", impact_speed_mps)
        return v, v
    try:
        lo, hi = speed_range_mps  # type: ignore[misc]
    except (TypeError, ValueError):
        raise ContactModelError(
            f"speed_range_mps must be two speeds (v_lo, v_hi), got {speed_range_mps!r}"
        ) from None
    lo, hi = positive("speed_range_mps[0]", lo), positive("speed_range_mps[1]", hi)
    if lo > hi:
        raise ContactModelError(f"speed_range_mps must have v_lo <= v_hi, got ({lo:g}, {hi:g})")
    return lo, hi


def _speeds(lo: float, hi: float) -> np.ndarray:
    """Where gravity's shift is evaluated: the ends of the range and its geometric middle."""
    return np.array([lo]) if lo == hi else np.array([lo, math.sqrt(lo * hi), hi])


def evaluate(
    e: float,
    w0: float,
    dt: float,
    speeds: np.ndarray,
    g: float,
    integrator: str,
) -> Evaluation:
    """Calibrate zeta at stiffness w0**2 for target e and predict the errors.

    zeta and gravity's shift depend on each other: a few fixed-point iterations. The shift is
    piecewise constant in zeta (the step in which the ball is back at the surface jumps by one
    for one phase: about h g / (w0 v) / 16), so the iteration stops at 1e-4.

    Raises:
        ContactModelError: gravity's shift cannot be calibrated out at this stiffness.
    """
    scheme = scheme_of(integrator)
    cap = table(scheme).w0dt_max
    h = min(w0 * dt, cap)
    ratios = g / (w0 * speeds) if g > 0.0 else np.zeros(speeds.size)
    shift, spread, step = 0.0, 0.0, 0.0
    for _ in range(12):
        zeta = calibrated_zeta(_shifted(e, shift, ratios), h, scheme)
        if g <= 0.0:
            break
        s = np.asarray(gravity_shift(zeta, h, ratios, integrator))
        new = 0.5 * (float(s.max()) + float(s.min()))
        spread = 0.5 * (float(s.max()) - float(s.min()))
        step, shift = abs(new - shift), new
        if step <= 1e-4:
            break
    if step > 1e-3:
        raise ContactModelError(
            f"cannot calibrate e = {e:g} under gravity {g:g} m/s^2 with stiffness {w0 * w0:.4g} "
            f"(g / (w0 v) up to {ratios.max():.3g}): use a stiffer contact or a higher v_lo"
        )
    zeta = calibrated_zeta(_shifted(e, shift, ratios), h, scheme)
    _, phase, pen = discrete(zeta, h, scheme)
    return Evaluation(w0, zeta, shift, spread, phase, pen, w0 * dt)


def _shifted(e: float, shift: float, ratios: np.ndarray) -> float:
    """The zero-gravity e to calibrate for so that gravity's shift brings it to e."""
    target = e - shift
    if not RESTITUTION_FLOOR <= target <= 1.0:
        raise ContactModelError(
            f"e = {e:g} cannot be reached under gravity with g / (w0 v) up to "
            f"{float(np.max(ratios)):.3g}: gravity changes e by {shift:+.3g}; use a stiffer "
            "contact"
        )
    return target


def design_stiffness(
    e: float,
    *,
    bound_m: float | None,
    duration_s: float | None,
    dt: float,
    speeds: np.ndarray,
    g: float,
    integrator: str,
) -> Evaluation:
    """The stiffness rule (module docstring) and the calibrated contact it gives."""
    v_hi = float(speeds.max())
    if duration_s is not None:
        w0 = contact_time_factor(zeta_for_restitution(e)) / duration_s
        for _ in range(5):
            ev = evaluate(e, w0, dt, speeds, g, integrator)
            w0 = contact_time_factor(ev.zeta) / duration_s
        return evaluate(e, w0, dt, speeds, g, integrator)
    assert bound_m is not None
    w0 = v_hi * max_penetration_factor(zeta_for_restitution(e)) / bound_m
    for _ in range(16):
        ev = evaluate(e, w0, dt, speeds, g, integrator)
        w0_pen = v_hi * ev.pen / (0.995 * bound_m)
        # the half spread falls as 1 / w0 (to first order in g / (w0 v))
        w0_g = w0 * ev.spread / (0.99 * SPREAD_BUDGET)
        new = min(max(w0_pen, w0_g), 100.0 * w0)
        if abs(new - w0) <= 1e-4 * w0:
            break
        w0 = new
    return evaluate(e, w0, dt, speeds, g, integrator)


def contact_params(
    restitution: float,
    *,
    radius_m: float,
    timestep_s: float,
    speed_range_mps: Sequence[float] | None = None,
    impact_speed_mps: float | None = None,
    integrator: str = "Euler",
    duration_s: float | None = None,
    max_penetration_m: float | None = None,
    max_penetration_fraction: float = 0.02,
    gravity_mps2: float = 9.81,
    allow_coarse: bool = False,
) -> ContactParams:
    """Contact parameters (solref, solimp) that make MuJoCo deliver a restitution.

    No simulation: the closed form, the discretisation table and a closed-form evaluation of
    the step emulation for gravity's shift (a few ms).

    Args:
        restitution: target e, RESTITUTION_FLOOR <= e <= 1.
        radius_m: smaller radius of the two bodies in m (sets the default penetration bound).
        timestep_s: simulation timestep in s (the calibration is for this timestep).
        speed_range_mps: (v_lo, v_hi), the normal impact speeds in m/s at which e must be
            within RESTITUTION_TOLERANCE of the target.
        impact_speed_mps: a single impact speed instead of a range (v_lo = v_hi).
        integrator: MuJoCo's integrator ("Euler", "implicit", "implicitfast", "RK4").
        duration_s: contact duration in s; overrides the stiffness rule.
        max_penetration_m: max penetration in m at v_hi; overrides the default bound.
        max_penetration_fraction: default penetration bound as a fraction of radius_m.
        gravity_mps2: gravity along the contact normal in m/s^2 for a body on a fixed surface
            (0 for zero-gravity scenes and for two free bodies, whose relative motion gravity
            does not change).
        allow_coarse: warn instead of raising if the timestep does not resolve the contact.

    Returns:
        The calibrated :class:`ContactParams`.

    Raises:
        ContactModelError: unreachable restitution, invalid input, both duration_s and
            max_penetration_m given, or a timestep too coarse for the contact.
    """
    e = check_restitution(restitution)
    radius = positive("radius_m", radius_m)
    lo, hi = speed_range(speed_range_mps, impact_speed_mps)
    dt = positive("timestep_s", timestep_s)
    scheme_of(integrator)
    g = float(gravity_mps2)
    if not math.isfinite(g) or g < 0.0:
        raise ContactModelError(f"gravity_mps2 must be >= 0, got {gravity_mps2!r}")
    if duration_s is not None and max_penetration_m is not None:
        raise ContactModelError("give duration_s or max_penetration_m, not both")
    if duration_s is not None:
        duration_s = positive("duration_s", duration_s)
        bound = None
    elif max_penetration_m is not None:
        bound = positive("max_penetration_m", max_penetration_m)
    else:
        bound = positive("max_penetration_fraction", max_penetration_fraction) * radius
    ev = design_stiffness(
        e,
        bound_m=bound,
        duration_s=duration_s,
        dt=dt,
        speeds=_speeds(lo, hi),
        g=g,
        integrator=integrator,
    )
    params = params_from(ev, e, (lo, hi), dt, g, integrator)
    check_timestep(params, dt, allow_coarse=allow_coarse)
    return params


def params_from(
    ev: Evaluation,
    e: float,
    speeds: tuple[float, float],
    dt: float,
    g: float,
    integrator: str,
) -> ContactParams:
    """The ContactParams of an evaluated stiffness."""
    k = ev.w0 * ev.w0
    return ContactParams(
        solref=(-k, -2.0 * ev.zeta * ev.w0),
        solimp=SOLIMP,
        stiffness=k,
        damping=2.0 * ev.zeta * ev.w0,
        zeta=ev.zeta,
        duration_s=contact_time_factor(ev.zeta) / ev.w0,
        max_penetration_m=speeds[1] * ev.pen / ev.w0,
        restitution=e,
        speed_range_mps=speeds,
        timestep_s=dt,
        integrator=integrator,
        gravity_mps2=g,
        gravity_shift=ev.shift,
        gravity_spread=ev.spread,
        phase_error=ev.phase,
    )


def check_timestep(params: ContactParams, timestep_s: float, *, allow_coarse: bool = False) -> int:
    """Check that a timestep resolves the contact well enough for the restitution tolerance.

    The worst case over the speed range and over where in a step the contact begins is
    predicted from the calibration table: |midrange e(zeta, w0 dt) + gravity shift - target|
    + half range + gravity's half spread. It must be within PHASE_BUDGET (the tolerance
    minus 0.001 for the table's interpolation).

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
    dt = positive("timestep_s", timestep_s)
    scheme = scheme_of(params.integrator)
    w0 = math.sqrt(params.stiffness)
    w0dt = w0 * dt
    steps = int(params.duration_s / dt)
    e = params.restitution
    cap = table(scheme).w0dt_max
    mid, half, _ = discrete(params.zeta, min(w0dt, cap), scheme)
    err = abs(mid + params.gravity_shift - e) + half + params.gravity_spread
    too_coarse = w0dt > cap * (1.0 + 1e-9)
    if err <= PHASE_BUDGET + 1e-6 and not too_coarse:
        return steps
    msg = coarse_message(params, dt) if dt >= params.timestep_s * (1.0 - 1e-9) else None
    if msg is None:
        msg = (
            f"contact parameters were calibrated for timestep {params.timestep_s:.3g} s, not "
            f"{dt:.3g} s: predicted worst-case error {err:.4f} > {PHASE_BUDGET}; call "
            f"contact_params with timestep_s={dt:.6g}"
        )
    if allow_coarse:
        warnings.warn(msg, UserWarning, stacklevel=2)
        return steps
    raise ContactModelError(msg)


def coarse_message(params: ContactParams, dt: float) -> str:
    """Why a timestep is too coarse for a contact, and the largest one that works."""
    from impactlab.contact.advice import largest_timestep

    e, (lo, hi) = params.restitution, params.speed_range_mps
    steps = int(params.duration_s / dt)
    where = f"at {hi:g} m/s" if lo == hi else f"over {lo:g}..{hi:g} m/s"
    if params.gravity_spread >= PHASE_BUDGET:
        return (
            f"gravity changes e by +-{params.gravity_spread:.4f} {where} with this contact "
            f"(duration {params.duration_s:.3g} s): e = {e:.4g} within "
            f"{RESTITUTION_TOLERANCE} needs a shorter contact or a narrower speed range"
        )
    dt_max = largest_timestep(params)
    steps_needed = math.ceil(params.duration_s / dt_max)
    return (
        f"timestep {dt:.3g} s gives {steps} steps per contact (w0*dt = "
        f"{math.sqrt(params.stiffness) * dt:.3g}); e = {e:.4g} within {RESTITUTION_TOLERANCE} "
        f"{where} needs >= {steps_needed} steps, i.e. timestep <= {dt_max:.3g} s for "
        f"stiffness {params.stiffness:.4g} (or a softer contact: larger max penetration, "
        "longer duration, or a narrower speed range)"
    )
