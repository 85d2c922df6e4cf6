"""The designer: a target coefficient of restitution -> MuJoCo contact parameters.

MuJoCo has no restitution parameter (google-deepmind/mujoco issue #2080). This module uses the
direct form of ``solref`` (``(-stiffness, -damping)``) with a constant impedance close to 1, for
which a MuJoCo contact is a linear spring-dashpot in the contact's normal coordinate, independent
of the masses::

    a_normal = -k * dist - b * dist_dot        while the contact force is positive

The Schwager & Poeschel closed form (Granular Matter 9, 2007) gives e(zeta) for that law with the
contact ending when the force vanishes; it is inverted for zeta and then corrected for MuJoCo's
time discretisation with a table (``restitution_table.json``) computed once by an exact numpy
emulation of ``mj_step`` for this contact (the emulation matches ``mj_step`` to 1e-14; the
tests check it). Regenerate the table with ``python -m impactlab.contact.table``.

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
(:func:`impact_fast`, a few fixed-point iterations); :func:`surface_restitution` and
:func:`restitution_with_gravity` predict e at other speeds (lower below the design speed, higher
above it, by at most the shift).
"""

from __future__ import annotations

import math
import warnings

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
from impactlab.contact.emulation import SOLIMP
from impactlab.contact.gravity import gravity_shift
from impactlab.contact.params import ContactParams
from impactlab.contact.table import PHASE_BUDGET, calibrated_zeta, discrete, table, w0dt_max

RESTITUTION_TOLERANCE = 0.005
"""Accuracy promised for |e_measured - e_target| at the design point."""


GRAVITY_RATIO_MAX = 0.015
"""Default bound on g / (w0 * v_in) at the design speed. Gravity's shift of the surface-to-surface
e, about -2 zeta g / (w0 v), is calibrated out at the design speed; this bound keeps it (and so
the change of e with the impact speed) to about 0.02 at most."""


def shifted_target(e: float, shift: float, gravity_ratio: float) -> float:
    """The zero-gravity e to calibrate for so that gravity's shift brings it to e."""
    target = e - shift
    if not RESTITUTION_FLOOR <= target <= 1.0:
        raise ContactModelError(
            f"e = {e:g} cannot be reached under gravity with g / (w0 v) = {gravity_ratio:.3g}: "
            f"gravity changes e by {shift:+.3g} at the design speed; use a stiffer contact"
        )
    return target


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
    e = check_restitution(restitution)
    radius = positive("radius_m", radius_m)
    v = positive("impact_speed_mps", impact_speed_mps)
    dt = positive("timestep_s", timestep_s)
    g = float(gravity_mps2)
    if not math.isfinite(g) or g < 0.0:
        raise ContactModelError(f"gravity_mps2 must be >= 0, got {gravity_mps2!r}")
    if duration_s is not None and max_penetration_m is not None:
        raise ContactModelError("give duration_s or max_penetration_m, not both")

    wh_cap = table().w0dt_max

    def zeta_at(w0: float, shift: float) -> float:
        return calibrated_zeta(shifted_target(e, shift, g / (w0 * v)), min(w0 * dt, wh_cap))

    def shift_at(zeta: float, w0: float) -> float:
        return gravity_shift(zeta, min(w0 * dt, wh_cap), g / (w0 * v)) if g > 0.0 else 0.0

    # zeta is calibrated for the zero-gravity e, target - shift, where shift is gravity's change
    # of the surface-to-surface e at the design speed; shift depends on zeta and w0, w0 (through
    # the penetration or duration rule) on zeta: iterate both, then converge the shift at w0.
    shift = 0.0
    if duration_s is not None:
        tc = positive("duration_s", duration_s)
        w0 = contact_time_factor(zeta_for_restitution(e)) / tc
        for _ in range(4):
            z = zeta_at(w0, shift)
            w0 = contact_time_factor(z) / tc
            shift = shift_at(z, w0)
    else:
        if max_penetration_m is not None:
            bound = positive("max_penetration_m", max_penetration_m)
            w0_gravity = 0.0
        else:
            fraction = positive("max_penetration_fraction", max_penetration_fraction)
            bound = fraction * radius
            w0_gravity = g / (GRAVITY_RATIO_MAX * v)
        w0 = v * max_penetration_factor(zeta_for_restitution(e)) / bound
        for _ in range(6):
            z = zeta_at(w0, shift)
            pen = discrete(z, min(w0 * dt, wh_cap))[2]
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
    _, _, pen = discrete(zeta, min(w0dt, wh_cap))
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
    dt = positive("timestep_s", timestep_s)
    w0 = math.sqrt(params.stiffness)
    w0dt = w0 * dt
    steps = int(params.duration_s / dt)
    e = params.restitution
    mid, half, _ = discrete(params.zeta, min(w0dt, table().w0dt_max))
    err = abs(mid + params.gravity_shift - e) + half
    too_coarse = w0dt > table().w0dt_max * (1.0 + 1e-9)
    if err <= PHASE_BUDGET + 1e-6 and not too_coarse:
        return steps
    wh_max = w0dt_max(e)
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
            f"{dt:.3g} s: predicted worst-case error {err:.4f} > {PHASE_BUDGET}; call "
            f"contact_params with timestep_s={dt:.6g}"
        )
    if allow_coarse:
        warnings.warn(msg, UserWarning, stacklevel=2)
        return steps
    raise ContactModelError(msg)
