"""The designer: a target restitution over a range of impact speeds -> MuJoCo contact parameters."""

from __future__ import annotations

import decimal
import math
import warnings
from collections.abc import Sequence
from typing import Required, TypedDict, Unpack

from impactlab.contact.advice import ContactDesign, largest_passing, significant
from impactlab.contact.calibration import Request, evaluate, resolved, try_evaluate, w0dt_max
from impactlab.contact.closed_form import (
    ContactModelError,
    check_restitution,
    checked,
    contact_time_factor,
    max_penetration_factor,
    zeta_for_restitution,
)
from impactlab.contact.emulation import scheme_of
from impactlab.contact.params import ContactParams
from impactlab.contact.table import PHASE_BUDGET, RESTITUTION_TOLERANCE

SPEED_FLOOR_MPS = 0.5
"""Lowest impact speed of a default speed range, in m/s (specs and ``impactlab contact MODEL``):
below it a bounce is 1.3 cm high, and holding e there needs a much stiffer contact (gravity's
effect on e grows as 1 / v). Set the range explicitly to go lower."""

PENETRATION_FRACTION = 0.02
"""The default penetration bound at v_hi, as a fraction of the smaller radius."""

GRAVITY_RATIO_START = 0.015
"""g / (w0 v_lo) of the stiffness the iteration starts from."""

SPREAD_BUDGET = 0.0015
"""Default bound on gravity's half spread of e over the speed range: the default stiffness is
at least the one that keeps e(v_lo) and e(v_hi) within this of the target (on average over
step phases). The rest of ``PHASE_BUDGET`` goes to the phase error, so the timestep needed
depends on how wide the range is."""


def speed_range(
    speed_range_mps: Sequence[float] | None, impact_speed_mps: float | None
) -> tuple[float, float]:
    """(v_lo, v_hi) from a range or a single impact speed (a range of one speed).

    Raises:
        ContactModelError: neither or both given, not 0 < v_lo <= v_hi, or outside LIMITS.
    """
    if (speed_range_mps is None) == (impact_speed_mps is None):
        raise ContactModelError("give speed_range_mps = (v_lo, v_hi) or impact_speed_mps")
    if impact_speed_mps is not None:
        v = checked("impact_speed_mps", impact_speed_mps, "speed")
        return v, v
    try:
        lo, hi = speed_range_mps  # type: ignore[misc]
    except (TypeError, ValueError):
        raise ContactModelError(
            f"speed_range_mps must be two speeds (v_lo, v_hi), got {speed_range_mps!r}"
        ) from None
    lo, hi = checked("v_lo", lo, "speed"), checked("v_hi", hi, "speed")
    if lo > hi:
        raise ContactModelError(f"speed_range_mps must have v_lo <= v_hi, got ({lo:g}, {hi:g})")
    return lo, hi


def design_stiffness(
    request: Request, *, bound_m: float | None, duration_s: float | None
) -> ContactParams:
    """The stiffness rule (docs/contact-model.md, "The designer") and the calibrated contact
    it gives.

    Raises:
        ContactModelError: gravity's shift cannot be calibrated out at the stiffness found.
    """
    e, g, speeds = request.e, request.gravity_mps2, request.speeds
    v_hi = float(speeds.max())
    if duration_s is not None:
        w0 = contact_time_factor(zeta_for_restitution(e)) / duration_s
        for _ in range(5):
            w0 = contact_time_factor(evaluate(request, w0).zeta) / duration_s
        return evaluate(request, w0)
    assert bound_m is not None
    w0 = v_hi * max_penetration_factor(zeta_for_restitution(e)) / bound_m
    if g > 0.0:  # start where gravity's effect is small: the iteration softens if it may
        w0 = max(w0, g / (GRAVITY_RATIO_START * float(speeds.min())))
    for _ in range(16):
        found = try_evaluate(request, w0)
        if found is None:  # gravity's shift too large to calibrate out: stiffer
            w0 *= 4.0
            continue
        w0_pen = w0 * found.max_penetration_m / (0.995 * bound_m)
        # the half spread falls as 1 / w0 (to first order in g / (w0 v))
        w0_g = w0 * found.gravity_spread / (0.99 * SPREAD_BUDGET)
        new = min(max(w0_pen, w0_g), 100.0 * w0)
        if abs(new - w0) <= 1e-4 * w0:
            break
        w0 = new
    return evaluate(request, w0)


class DesignOptions(TypedDict, total=False):
    """`design_contact`'s keyword arguments, which `contact_params` takes too."""

    radius_m: Required[float | None]
    timestep_s: Required[float]
    speed_range_mps: Sequence[float] | None
    impact_speed_mps: float | None
    integrator: str
    duration_s: float | None
    max_penetration_m: float | None
    gravity_mps2: float


def design_contact(
    restitution: float,
    *,
    radius_m: float | None,
    timestep_s: float,
    speed_range_mps: Sequence[float] | None = None,
    impact_speed_mps: float | None = None,
    integrator: str = "Euler",
    duration_s: float | None = None,
    max_penetration_m: float | None = None,
    gravity_mps2: float = 9.81,
) -> ContactDesign:
    """Design a contact (solref, solimp) that makes MuJoCo deliver a restitution, and say how
    well it meets its target.

    No simulation: the closed form, the discretisation table and a closed-form evaluation of
    the step emulation for gravity's shift (a few ms).

    Args:
        restitution: target e, RESTITUTION_FLOOR <= e <= 1.
        radius_m: smaller radius of the two bodies in m (the default penetration bound is
            PENETRATION_FRACTION of it); may be None when ``max_penetration_m`` or
            ``duration_s`` is given.
        timestep_s: simulation timestep in s (the calibration is for this timestep).
        speed_range_mps: (v_lo, v_hi), the normal impact speeds in m/s at which e must be
            within RESTITUTION_TOLERANCE of the target.
        impact_speed_mps: a single impact speed instead of a range (v_lo = v_hi).
        integrator: MuJoCo's integrator ("Euler", "implicit", "implicitfast", "RK4").
        duration_s: contact duration in s; overrides the stiffness rule.
        max_penetration_m: max penetration in m at v_hi; overrides the default bound.
        gravity_mps2: gravity along the contact normal in m/s^2 for a body on a fixed surface
            (0 for zero-gravity scenes and for two free bodies, whose relative motion gravity
            does not change).

    Returns:
        The :class:`ContactDesign`; ``ok`` is False (with the advice filled in when asked)
        when the timestep cannot resolve the contact (``problem`` names the steps per
        contact and the largest timestep that works).

    Raises:
        ContactModelError: an unreachable target; a value of the wrong type or outside
            LIMITS; both a duration and a max penetration; none of radius, max penetration
            and duration.
    """
    scheme_of(integrator)
    request = Request(
        check_restitution(restitution),
        speed_range(speed_range_mps, impact_speed_mps),
        checked("timestep_s", timestep_s),
        integrator,
        checked("gravity_mps2", gravity_mps2),
    )
    bound = duration = None
    if duration_s is not None and max_penetration_m is not None:
        raise ContactModelError("give duration_s or max_penetration_m, not both")
    if duration_s is not None:
        duration = checked("duration_s", duration_s)
    elif max_penetration_m is not None:
        bound = checked("max_penetration_m", max_penetration_m)
    elif radius_m is None:
        raise ContactModelError("give a radius, a max penetration or a contact duration")
    else:
        bound = PENETRATION_FRACTION * checked("radius_m", radius_m)
    params = design_stiffness(request, bound_m=bound, duration_s=duration)
    if resolved(params):
        return ContactDesign(params)
    dt_max = None
    if params.gravity_spread < PHASE_BUDGET:  # the bound as printed is accepted when used
        dt_max = largest_timestep(params, bound, duration)
    return ContactDesign(params, timestep_problem(params, dt_max), dt_max)


def contact_params(
    restitution: float, *, allow_coarse: bool = False, **options: Unpack[DesignOptions]
) -> ContactParams:
    """The parameters of :func:`design_contact` (same arguments), or an error when the
    timestep does not resolve the contact (a warning with ``allow_coarse``).

    Raises:
        ContactModelError: as :func:`design_contact`, and the design's ``problem`` when the
            timestep is too coarse.
    """
    found = design_contact(restitution, **options)
    if found.problem is not None:
        if not allow_coarse:
            raise ContactModelError(found.problem)
        warnings.warn(found.problem, UserWarning, stacklevel=2)
    return found.params


def largest_timestep(
    designed: ContactParams, bound_m: float | None, duration_s: float | None
) -> float:
    """The largest timestep (three significant digits, as messages print it) at which the
    same request (target, speeds, penetration bound or duration) is met by the design made
    for that timestep: a timestep named as the bound is accepted when used as printed.

    First the largest at which the designed stiffness meets the tolerance (about 1 %): halved
    from the table's coarsest step until it does, then bisected. From there down one unit of
    the last digit at a time until the design made for the timestep passes (its stiffness
    depends on the timestep, so the estimate may be a little too large); the last one tried
    when none passes in 40 steps.
    """
    w0 = math.sqrt(designed.stiffness)

    def stiffness_passes(dt: float) -> bool:
        return resolved(try_evaluate(Request.of(designed, timestep_s=dt), w0))

    def design_passes(dt: float) -> bool:
        request = Request.of(designed, timestep_s=dt)
        try:
            return resolved(design_stiffness(request, bound_m=bound_m, duration_s=duration_s))
        except ContactModelError:
            return False

    hi = estimate = w0dt_max(designed.integrator) / w0
    if not stiffness_passes(hi):
        lo = estimate = hi / 2.0
        for _ in range(40):
            if stiffness_passes(lo):
                estimate = largest_passing(stiffness_passes, lo, hi, ratio=1.0002)
                break
            hi, lo = lo, lo / 2.0
            estimate = lo
    dt = significant(estimate, decimal.ROUND_FLOOR)
    for _ in range(40):
        if dt <= 0 or design_passes(dt):
            return dt
        last = decimal.Decimal(repr(dt))
        dt = float(last - decimal.Decimal(f"1e{last.adjusted() - 2}"))
    return dt


def timestep_problem(params: ContactParams, timestep_max_s: float | None) -> str:
    """Why the contact's timestep does not resolve it: gravity's spread over the speed range
    alone is beyond the budget, or the steps per contact and those needed, with the largest
    timestep that works (`timestep_max_s`)."""
    dt, e, (lo, hi) = params.timestep_s, params.restitution, params.speed_range_mps
    where = f"at {hi:g} m/s" if lo == hi else f"over {lo:g}..{hi:g} m/s"
    if params.gravity_spread >= PHASE_BUDGET or timestep_max_s is None:
        return (
            f"gravity changes e by +-{params.gravity_spread:.4f} {where} with this contact "
            f"(duration {params.duration_s:.3g} s): e = {e:.4g} within "
            f"{RESTITUTION_TOLERANCE} needs a shorter contact or a narrower speed range"
        )
    w0dt = math.sqrt(params.stiffness) * dt
    return (
        f"timestep {dt:.3g} s gives {int(params.duration_s / dt)} steps per contact (w0*dt = "
        f"{w0dt:.3g}); e = {e:.4g} within {RESTITUTION_TOLERANCE} {where} needs >= "
        f"{math.ceil(params.duration_s / timestep_max_s)} steps, i.e. timestep <= "
        f"{timestep_max_s:.3g} s for stiffness {params.stiffness:.4g} (or a softer contact: "
        "larger max penetration, longer duration, or a narrower speed range)"
    )
