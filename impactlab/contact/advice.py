"""A contact design with what a user needs to judge it: predictions, and advice when it misses."""

from __future__ import annotations

import decimal
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from impactlab.contact import curvefit
from impactlab.contact.calibration import Request, resolved, shift_speeds, try_evaluate, w0dt_max
from impactlab.contact.curve import RestitutionCurve
from impactlab.contact.emulation import restitution_spread
from impactlab.contact.params import ContactParams
from impactlab.contact.shaped import emulate

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

    def worst_error(self, target: float | RestitutionCurve) -> float:
        """Largest |e - target| of a single impact at a speed in the range."""
        at = [
            float(target.at(v)) if isinstance(target, RestitutionCurve) else target
            for v in self.speeds_mps
        ]
        errs = [
            max(abs(lo - t), abs(hi - t))
            for lo, hi, t, inside in zip(self.lowest, self.highest, at, self.in_range, strict=True)
            if inside
        ]
        return max(errs, default=float("nan"))

    def e_range(self) -> tuple[float, float]:
        """Lowest and highest e of a single impact in the speed range."""
        inside = [i for i, ok in enumerate(self.in_range) if ok]
        return min(self.lowest[i] for i in inside), max(self.highest[i] for i in inside)


@dataclass(frozen=True)
class ContactDesign:
    """A designed contact and how well it meets its target (`design_contact`).

    Attributes:
        params: the designed contact (for the given timestep, even when too coarse), with its
            predicted errors.
        problem: why the timestep does not resolve it, or None.
        timestep_max_s: the largest timestep at which this contact meets the target (None
            when the timestep is fine or no timestep helps).
    """

    params: ContactParams
    problem: str | None = None
    timestep_max_s: float | None = None

    @property
    def ok(self) -> bool:
        """The predicted worst case meets the tolerance at the given timestep."""
        return self.problem is None

    @functools.cached_property
    def prediction(self) -> Prediction:
        """e over (and below) the speed range at the given timestep."""
        return predict(self.params)

    @functools.cached_property
    def best(self) -> ContactParams | None:
        """The most accurate contact at the given timestep (None when ok)."""
        return None if self.ok or self.params.curve is not None else _best(self.params)

    @functools.cached_property
    def best_prediction(self) -> Prediction | None:
        """e of `best` over (and below) the speed range, or None."""
        return None if self.best is None else predict(self.best)

    @functools.cached_property
    def softer(self) -> ContactParams | None:
        """The stiffest contact that meets the target at the given timestep (more
        penetration than asked for), or None."""
        best = self.best
        if best is None or not resolved(best) or best.stiffness >= self.params.stiffness:
            return None
        request, w_best = Request.of(best), math.sqrt(best.stiffness)
        edge = largest_passing(
            lambda w0: resolved(try_evaluate(request, w0)),
            w_best,
            math.sqrt(self.params.stiffness),
            ratio=1.002,
        )
        # a little softer than the edge: the designer asked for that penetration makes the
        # contact 0.5 % stiffer than the bound needs
        for w0 in (max(w_best, 0.97 * edge), edge):
            found = try_evaluate(request, w0)
            if resolved(found):
                return found
        return best

    @property
    def notes(self) -> tuple[str, ...]:
        """Remarks for the user."""
        dt_max = self.timestep_max_s
        if dt_max is not None and dt_max < 1e-7:
            return (f"the largest timestep that works, {dt_max:.3g} s, is impractically small",)
        return ()


def predict(params: ContactParams) -> Prediction:
    """e over the speed range and at fractions BELOW_RANGE of v_lo.

    Over the range: twice as dense as where the designer evaluates gravity's shift (those
    speeds included), at least 7 speeds.
    """
    lo, hi = params.speed_range_mps
    if params.curve is not None:
        return _predict_curve(params)
    n = max(7, 2 * len(shift_speeds(lo, hi)) - 1)
    inside = list(np.geomspace(lo, hi, n)) if hi > lo else [lo]
    outside = [lo * f for f in BELOW_RANGE] if params.gravity_mps2 > 0.0 else []
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


def _predict_curve(params: ContactParams) -> Prediction:
    """e of a curve's contact over its range (the curve's points and CHECK_SPEEDS between,
    CHECK_PHASES step phases each), by the step emulation of its impedance."""
    assert params.curve is not None
    lo, hi = params.speed_range_mps
    speeds = curvefit.fit_speeds(params.curve, lo, hi, curvefit.CHECK_SPEEDS)
    phases = (np.arange(curvefit.CHECK_PHASES) + 0.5) / curvefit.CHECK_PHASES
    found = emulate(
        np.array(params.solref)[None, None, :],
        np.array(params.solimp)[None, None, :],
        speeds[:, None],
        phases[None, :],
        timestep_s=curvefit.emulated_timestep(params.timestep_s, math.sqrt(params.stiffness)),
        gravity_mps2=params.gravity_mps2,
        integrator=params.integrator,
        max_time_s=40.0 / math.sqrt(params.stiffness) + 4.0 * params.solimp[2] / lo,
    )
    return Prediction(
        speeds_mps=tuple(float(v) for v in speeds),
        mean=tuple(float(x) for x in found.e.mean(1)),
        lowest=tuple(float(x) for x in found.e.min(1)),
        highest=tuple(float(x) for x in found.e.max(1)),
        in_range=(True,) * speeds.size,
    )


def _best(designed: ContactParams) -> ContactParams | None:
    """The stiffness with the smallest predicted error at dt (golden section in log w0, up to
    four times the designed one)."""
    asked = Request.of(designed)
    dt, g, speeds = asked.timestep_s, asked.gravity_mps2, asked.speeds
    w_hi = min(math.sqrt(designed.stiffness) * 4.0, w0dt_max(asked.integrator) / dt)
    w_lo = w_hi * 1e-4 if g <= 0.0 else max(g / (0.3 * float(speeds.min())), w_hi * 1e-4)
    if w_lo >= w_hi:
        return None

    def cost(lw: float) -> float:
        found = try_evaluate(asked, math.exp(lw))
        return math.inf if found is None else found.predicted_error

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
    return try_evaluate(asked, math.exp(c if fc <= fd else d))


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
