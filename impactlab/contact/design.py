"""The designer: a target restitution over a range of impact speeds -> MuJoCo contact parameters."""

from __future__ import annotations

import decimal
import math
import warnings
from collections.abc import Sequence
from typing import Required, TypedDict, Unpack

from impactlab.contact import curvefit
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
from impactlab.contact.curve import RestitutionCurve
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
    reference_speed_mps: float | None


def size_rule(
    radius_m: float | None,
    max_penetration_m: float | None,
    duration_s: float | None,
    fraction: float,
) -> tuple[float | None, float | None]:
    """(penetration bound, contact duration), one of them None: the duration or the max
    penetration given, else `fraction` of the radius.

    Raises:
        ContactModelError: both given, or none of the three; a value outside LIMITS.
    """
    if duration_s is not None and max_penetration_m is not None:
        raise ContactModelError("give duration_s or max_penetration_m, not both")
    if duration_s is not None:
        return None, checked("duration_s", duration_s)
    if max_penetration_m is not None:
        return checked("max_penetration_m", max_penetration_m), None
    if radius_m is None:
        raise ContactModelError("give a radius, a max penetration or a contact duration")
    return fraction * checked("radius_m", radius_m), None


class CurveOutOfReach(ContactModelError):
    """A target e(v) the contact cannot follow within CURVE_TOLERANCE: `design` holds the
    nearest reachable contact (its params' ``curve`` the target, ``phase_error`` its worst
    error), ``design.problem`` says why, ``design.timestep_max_s`` a timestep that did better
    when fitted at (None if none)."""

    def __init__(self, design: ContactDesign) -> None:
        super().__init__(design.problem)
        self.design = design


def design_for_curve(
    curve: RestitutionCurve,
    *,
    radius_m: float | None,
    timestep_s: float,
    speed_range_mps: Sequence[float] | None,
    impact_speed_mps: float | None,
    integrator: str,
    duration_s: float | None,
    max_penetration_m: float | None,
    gravity_mps2: float,
    reference_speed_mps: float | None,
) -> ContactDesign:
    """:func:`design_contact` for a target e(v): direct-form solref and a rising impedance
    fitted by the step emulation (docs/contact-model.md, "A target e(v)"), checked on a dense
    grid of speeds and step phases.

    Raises:
        CurveOutOfReach: the worst error over the range is above CURVE_TOLERANCE.
        ContactModelError: a range outside the curve's span, a reference speed outside the
            range, and the errors of :func:`design_contact`.
    """
    span = curve.span_mps
    if speed_range_mps is None and impact_speed_mps is None:
        lo, hi = span
    else:
        lo, hi = speed_range(speed_range_mps, impact_speed_mps)
        if lo < span[0] * (1 - 1e-12) or hi > span[1] * (1 + 1e-12):
            raise ContactModelError(
                f"the speeds {lo:g}..{hi:g} m/s reach outside the curve's points "
                f"({span[0]:g}..{span[1]:g} m/s): a curve promises no e outside them"
            )
        lo, hi = max(lo, span[0]), min(hi, span[1])
    if hi > curvefit.MAX_SPAN * lo:
        raise ContactModelError(
            f"the speeds {lo:g}..{hi:g} m/s span more than {curvefit.MAX_SPAN:g} times: design "
            "a curve over a narrower range"
        )
    ref = (
        hi
        if reference_speed_mps is None
        else checked("reference_speed_mps", reference_speed_mps, "speed")
    )
    if not lo * (1 - 1e-12) <= ref <= hi * (1 + 1e-12):
        raise ContactModelError(
            f"reference_speed_mps = {ref:g} is outside the speeds {lo:g}..{hi:g} m/s"
        )
    bound, duration = size_rule(
        radius_m, max_penetration_m, duration_s, curvefit.CURVE_PENETRATION_FRACTION
    )
    setting = curvefit.Setting(
        (lo, hi),
        checked("timestep_s", timestep_s),
        integrator,
        checked("gravity_mps2", gravity_mps2),
    )
    found = curvefit.cached_design(curve, setting, bound, duration, ref)
    if not math.isfinite(found.contact_s):
        raise ContactModelError(
            f"the ball does not leave the fitted contact at {ref:g} m/s within 40 contact "
            "times: a higher lowest speed or a stiffer contact"
        )
    params = curve_params(curve, setting, found, ref)
    if found.worst_error <= curvefit.CURVE_TOLERANCE:
        return ContactDesign(params)
    better = curvefit.better_timestep(
        curve, setting, found, bound_m=bound, duration_s=duration, reference_mps=ref
    )
    raise CurveOutOfReach(
        ContactDesign(
            params, out_of_reach(params, found, better), None if better is None else better[0]
        )
    )


def curve_params(
    curve: RestitutionCurve, setting: curvefit.Setting, found: curvefit.Checked, ref: float
) -> ContactParams:
    """The ContactParams of a fitted curve (see ContactParams for what each field holds)."""
    k, b = (-x for x in found.fit.solref)
    return ContactParams(
        solref=found.fit.solref,
        solimp=found.fit.solimp,
        stiffness=k,
        damping=b,
        zeta=b / (2.0 * math.sqrt(k)),
        duration_s=found.contact_s,
        max_penetration_m=found.penetration_m,
        restitution=float(curve.at(ref)),
        speed_range_mps=setting.speed_range_mps,
        timestep_s=setting.timestep_s,
        integrator=setting.integrator,
        gravity_mps2=setting.gravity_mps2,
        phase_error=found.worst_error,
        curve=curve,
        reference_speed_mps=ref,
        curve_achieved=found.achieved,
    )


def out_of_reach(
    params: ContactParams, found: curvefit.Checked, better: tuple[float, float] | None
) -> str:
    """Why a curve is refused: the nearest reachable curve, its worst error, and the timestep
    that did better when fitted at."""
    assert params.curve is not None
    lo, hi = params.speed_range_mps
    nearest = ", ".join(
        f"{v:g}:{e:.3f}" for v, e in zip(params.curve.speed_mps, found.achieved, strict=True)
    )
    text = (
        f"the contact cannot follow this e(v) within {curvefit.CURVE_TOLERANCE} over "
        f"{lo:g}..{hi:g} m/s at timestep {params.timestep_s:g} s ({params.integrator}): the "
        f"nearest reachable curve is e = {nearest} (speed:e, mean over step phases), worst "
        f"|e - target| {found.worst_error:.4f} between and at the points"
    )
    if better is None:
        return text + (
            f"; fitting at {params.timestep_s / 2:g} s does not do better: the curve changes "
            "too fast with speed for this contact model (a flatter curve or a narrower range)"
        )
    return text + (
        f"; fitted at timestep {better[0]:g} s the worst error is {better[1]:.4f} (measured)"
    )


def design_contact(
    target: float | RestitutionCurve,
    *,
    radius_m: float | None,
    timestep_s: float,
    speed_range_mps: Sequence[float] | None = None,
    impact_speed_mps: float | None = None,
    integrator: str = "Euler",
    duration_s: float | None = None,
    max_penetration_m: float | None = None,
    gravity_mps2: float = 9.81,
    reference_speed_mps: float | None = None,
) -> ContactDesign:
    """Design a contact (solref, solimp) that makes MuJoCo deliver a restitution, and say how
    well it meets its target.

    No simulation: the closed form, the discretisation table and a closed-form evaluation of
    the step emulation for gravity's shift (a few ms).

    A curve is fitted instead (:func:`design_for_curve`, seconds).

    Args:
        target: target e, RESTITUTION_FLOOR <= e <= 1, or a target e(v).
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
        reference_speed_mps: for a curve, the impact speed at which ``duration_s`` applies
            (default: the top of the range).

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
    if isinstance(target, RestitutionCurve):
        return design_for_curve(
            target,
            radius_m=radius_m,
            timestep_s=timestep_s,
            speed_range_mps=speed_range_mps,
            impact_speed_mps=impact_speed_mps,
            integrator=integrator,
            duration_s=duration_s,
            max_penetration_m=max_penetration_m,
            gravity_mps2=gravity_mps2,
            reference_speed_mps=reference_speed_mps,
        )
    if reference_speed_mps is not None:
        raise ContactModelError(
            "reference_speed_mps is for a target e(v): a constant e has one contact time"
        )
    request = Request(
        check_restitution(target),
        speed_range(speed_range_mps, impact_speed_mps),
        checked("timestep_s", timestep_s),
        integrator,
        checked("gravity_mps2", gravity_mps2),
    )
    bound, duration = size_rule(radius_m, max_penetration_m, duration_s, PENETRATION_FRACTION)
    params = design_stiffness(request, bound_m=bound, duration_s=duration)
    if resolved(params):
        return ContactDesign(params)
    dt_max = None
    if params.gravity_spread < PHASE_BUDGET:  # the bound as printed is accepted when used
        dt_max = largest_timestep(params, bound, duration)
    return ContactDesign(params, timestep_problem(params, dt_max), dt_max)


def contact_params(
    target: float | RestitutionCurve,
    *,
    allow_coarse: bool = False,
    **options: Unpack[DesignOptions],
) -> ContactParams:
    """The parameters of :func:`design_contact` (same arguments), or an error when the
    timestep does not resolve the contact or the curve is beyond reach (a warning with
    ``allow_coarse``, and the contact as designed or the nearest curve's).

    Raises:
        ContactModelError: as :func:`design_contact`, and the design's ``problem`` when the
            timestep is too coarse.
    """
    try:
        found = design_contact(target, **options)
    except CurveOutOfReach as exc:
        if not allow_coarse:
            raise
        found = exc.design
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
