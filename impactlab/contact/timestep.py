"""Does a timestep resolve a contact? If not: why, and the largest timestep that works."""

from __future__ import annotations

import dataclasses
import decimal
import math
from collections.abc import Callable

from impactlab.contact.calibration import Evaluation, evaluate
from impactlab.contact.closed_form import ContactModelError
from impactlab.contact.params import ContactParams
from impactlab.contact.table import PHASE_BUDGET, RESTITUTION_TOLERANCE


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


def largest_timestep(designed: Evaluation) -> float:
    """The largest timestep at which the designed stiffness meets the tolerance (about 1 %):
    halved from the table's coarsest step until it does, then bisected."""
    w0 = designed.w0

    def ok(dt: float) -> bool:
        try:
            return evaluate(dataclasses.replace(designed.request, timestep_s=dt), w0).resolved
        except ContactModelError:
            return False

    hi = designed.w0dt_max / w0
    if ok(hi):
        return hi
    lo = hi / 2.0
    for _ in range(40):
        if ok(lo):
            return largest_passing(ok, lo, hi, ratio=1.0002)
        hi, lo = lo, lo / 2.0
    return lo


def largest_passing(ok: Callable[[float], bool], lo: float, hi: float, *, ratio: float) -> float:
    """The largest x found with ok(x) between lo (ok) and hi (not ok): bisected geometrically
    until hi / lo < ratio."""
    while hi / lo >= ratio:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo


def significant(value: float, rounding: str, digits: int = 3) -> float:
    """`value` to `digits` significant digits of its printed form, rounded as `rounding`
    says (``decimal.ROUND_FLOOR``: never above `value`, ``ROUND_CEILING``: never below)."""
    exact = decimal.Decimal(repr(value))
    unit = decimal.Decimal(f"1e{exact.adjusted() - digits + 1}")
    return float(exact.quantize(unit, rounding=rounding))


def accepted_timestep(
    estimate: float, passes: Callable[[float], bool], *, digits: int = 3, tries: int = 40
) -> float:
    """The largest timestep of `digits` significant digits, at most `estimate`, at which
    `passes` (a design made for that timestep meets its target), stepping down one unit of
    the last digit at a time (the design's stiffness depends on the timestep, so the
    estimate of a design at another timestep may be a little too large).

    Returns the last one tried if none passes in `tries` steps.
    """
    dt = significant(estimate, decimal.ROUND_FLOOR, digits)
    for _ in range(tries):
        if dt <= 0 or passes(dt):
            return dt
        last = decimal.Decimal(repr(dt))
        dt = float(last - decimal.Decimal(f"1e{last.adjusted() - digits + 1}"))
    return dt
