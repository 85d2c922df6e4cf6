"""A contact design with what a user needs to judge it: predictions, and advice when it misses."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from impactlab.contact.calibration import Evaluation, evaluate, shift_speeds
from impactlab.contact.closed_form import ContactModelError
from impactlab.contact.design import design, params_from
from impactlab.contact.emulation import scheme_of
from impactlab.contact.gravity import restitution_spread
from impactlab.contact.params import ContactParams
from impactlab.contact.table import table

MIN_EMULATED_W0DT = 0.002
BELOW_RANGE = (0.25, 0.5)
"""Speeds below the range at which the drift is predicted, as fractions of v_lo."""


@dataclass(frozen=True)
class Prediction:
    """e predicted by the step emulation at impact speeds (64 contact-onset phases each).

    Attributes:
        speeds_mps: impact speeds in m/s, increasing.
        mean: mean e over phases, per speed.
        lowest, highest: extremes over phases, per speed.
        in_range: whether the speed is inside the contact's speed range.
    """

    speeds_mps: tuple[float, ...]
    mean: tuple[float, ...]
    lowest: tuple[float, ...]
    highest: tuple[float, ...]
    in_range: tuple[bool, ...]

    def worst_error(self, target: float) -> float:
        """Largest |e - target| of a single impact at a speed in the range."""
        errs = [
            max(abs(lo - target), abs(hi - target))
            for lo, hi, inside in zip(self.lowest, self.highest, self.in_range, strict=True)
            if inside
        ]
        return max(errs, default=float("nan"))

    def e_range(self) -> tuple[float, float]:
        """Lowest and highest e of a single impact in the speed range."""
        inside = [i for i, ok in enumerate(self.in_range) if ok]
        return min(self.lowest[i] for i in inside), max(self.highest[i] for i in inside)


@dataclass(frozen=True)
class ContactDesign:
    """A designed contact and how well it meets its target (see the module docstring).

    Attributes:
        params: the designed contact (for the given timestep, even when too coarse).
        ok: the predicted worst case meets the tolerance at the given timestep.
        problem: why not, or None.
        prediction: e over (and below) the speed range at the given timestep.
        timestep_max_s: the largest timestep at which this contact meets the target (None
            when the timestep is fine or no timestep helps).
        best: the most accurate contact at the given timestep (None when ok).
        softer: the stiffest contact that meets the target at the given timestep (more
            penetration than asked for), or None.
        best_prediction: e of `best` over (and below) the speed range, or None.
        notes: remarks for the user.
    """

    params: ContactParams
    ok: bool
    problem: str | None
    prediction: Prediction
    timestep_max_s: float | None = None
    best: ContactParams | None = None
    softer: ContactParams | None = None
    best_prediction: Prediction | None = None
    notes: tuple[str, ...] = field(default=())


def predict(params: ContactParams, *, below: Sequence[float] = BELOW_RANGE) -> Prediction:
    """e over the speed range and at fractions `below` of v_lo.

    Over the range: twice as dense as where the designer evaluates gravity's shift (those
    speeds included), at least 7 speeds.
    """
    lo, hi = params.speed_range_mps
    n = max(7, 2 * len(shift_speeds(lo, hi)) - 1)
    inside = list(np.geomspace(lo, hi, n)) if hi > lo else [lo]
    outside = [lo * f for f in below] if params.gravity_mps2 > 0.0 else []
    speeds = np.array(sorted(outside) + inside)
    # below w0 dt = 0.002 (some 1500 steps per contact) the phase error is under 2e-4 and
    # shrinks in proportion: emulate at 0.002, which bounds it from above, not step by step
    dt = max(params.timestep_s, MIN_EMULATED_W0DT / math.sqrt(params.stiffness))
    mean, lowest, highest = restitution_spread(
        params, impact_speed_mps=speeds, gravity_mps2=params.gravity_mps2, timestep_s=dt
    )
    return Prediction(
        speeds_mps=tuple(float(v) for v in speeds),
        mean=tuple(float(x) for x in mean),
        lowest=tuple(float(x) for x in lowest),
        highest=tuple(float(x) for x in highest),
        in_range=tuple(bool(lo * (1 - 1e-12) <= v <= hi * (1 + 1e-12)) for v in speeds),
    )


def _try(
    e: float, w0: float, dt: float, speeds: np.ndarray, g: float, integrator: str
) -> Evaluation | None:
    try:
        return evaluate(e, w0, dt, speeds, g, integrator)
    except ContactModelError:
        return None


def _best(
    e: float, dt: float, speeds: np.ndarray, g: float, integrator: str, w0_hi: float
) -> Evaluation | None:
    """The stiffness with the smallest predicted error at dt (golden section in log w0)."""
    cap = table(scheme_of(integrator)).w0dt_max
    w_hi = min(w0_hi * 4.0, cap / dt)
    w_lo = w_hi * 1e-4 if g <= 0.0 else max(g / (0.3 * float(speeds.min())), w_hi * 1e-4)
    if w_lo >= w_hi:
        return None

    def cost(lw: float) -> float:
        ev = _try(e, math.exp(lw), dt, speeds, g, integrator)
        return math.inf if ev is None else ev.error

    a, b = math.log(w_lo), math.log(w_hi)
    r = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = b - r * (b - a), a + r * (b - a)
    fc, fd = cost(c), cost(d)
    for _ in range(30):
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - r * (b - a)
            fc = cost(c)
        else:
            a, c, fc = c, d, fd
            d = a + r * (b - a)
            fd = cost(d)
    return _try(e, math.exp(c if fc <= fd else d), dt, speeds, g, integrator)


def _stiffest_ok(
    e: float,
    dt: float,
    speeds: np.ndarray,
    g: float,
    integrator: str,
    soft: Evaluation,
    stiff_w0: float,
) -> Evaluation:
    """The stiffest w0 between soft.w0 (meets the target) and stiff_w0 (does not) that does."""
    lo, hi = soft.w0, stiff_w0
    best = soft
    for _ in range(30):
        mid = math.sqrt(lo * hi)
        ev = _try(e, mid, dt, speeds, g, integrator)
        if ev is not None and ev.resolved:
            lo, best = mid, ev
        else:
            hi = mid
        if hi / lo < 1.002:
            break
    return best


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
    max_penetration_fraction: float = 0.02,
    gravity_mps2: float = 9.81,
) -> ContactDesign:
    """Design a contact like :func:`contact_params` and say how well it meets its target.

    Args: as :func:`contact_params`; ``radius_m`` may be None when ``max_penetration_m`` or
    ``duration_s`` is given.

    Returns:
        The :class:`ContactDesign`; ``ok`` is False (with the advice filled in) when the
        timestep cannot resolve the contact.

    Raises:
        ContactModelError: invalid input or an unreachable target.
    """
    found = design(
        restitution,
        radius_m=radius_m,
        timestep_s=timestep_s,
        speed_range_mps=speed_range_mps,
        impact_speed_mps=impact_speed_mps,
        integrator=integrator,
        duration_s=duration_s,
        max_penetration_m=max_penetration_m,
        max_penetration_fraction=max_penetration_fraction,
        gravity_mps2=gravity_mps2,
    )
    params, ev, speeds, dt_max = found.params, found.evaluation, found.speeds, found.timestep_max_s
    if found.problem is None:
        return ContactDesign(params, True, None, predict(params))
    e, (lo, hi), dt, g = (
        params.restitution,
        params.speed_range_mps,
        params.timestep_s,
        params.gravity_mps2,
    )
    best_ev = _best(e, dt, speeds, g, integrator, ev.w0)
    best = softer = None
    if best_ev is not None:
        best = params_from(best_ev, e, (lo, hi), dt, g, integrator)
        if best_ev.resolved and best_ev.w0 < ev.w0:
            soft_ev = _stiffest_ok(e, dt, speeds, g, integrator, best_ev, ev.w0)
            # a little softer than the edge: the designer asked for that penetration makes
            # the contact 0.5 % stiffer than the bound needs
            eased = _try(e, max(best_ev.w0, 0.97 * soft_ev.w0), dt, speeds, g, integrator)
            soft_ev = eased if eased is not None and eased.resolved else soft_ev
            softer = params_from(soft_ev, e, (lo, hi), dt, g, integrator)
    notes: tuple[str, ...] = ()
    if dt_max is not None and dt_max < 1e-7:
        notes = (f"the largest timestep that works, {dt_max:.3g} s, is impractically small",)
    return ContactDesign(
        params,
        False,
        found.problem,
        predict(params),
        timestep_max_s=dt_max,
        best=best,
        softer=softer,
        best_prediction=None if best is None else predict(best),
        notes=notes,
    )
