"""A contact design with what a user needs to judge it: predictions, and advice when it misses."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from impactlab.contact.calibration import Evaluation, Request, evaluate, shift_speeds
from impactlab.contact.closed_form import ContactModelError
from impactlab.contact.gravity import restitution_spread
from impactlab.contact.params import ContactParams
from impactlab.contact.timestep import largest_passing

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
    """A designed contact and how well it meets its target (`design_contact`).

    Attributes:
        evaluation: its stiffness evaluated for the request (zeta, the predicted errors).
        problem: why the timestep does not resolve it, or None.
        timestep_max_s: the largest timestep at which this contact meets the target (None
            when the timestep is fine or no timestep helps).
    """

    evaluation: Evaluation
    problem: str | None = None
    timestep_max_s: float | None = None

    @functools.cached_property
    def params(self) -> ContactParams:
        """The designed contact (for the given timestep, even when too coarse)."""
        return self.evaluation.params

    @property
    def ok(self) -> bool:
        """The predicted worst case meets the tolerance at the given timestep."""
        return self.problem is None

    @functools.cached_property
    def prediction(self) -> Prediction:
        """e over (and below) the speed range at the given timestep."""
        return predict(self.params)

    @functools.cached_property
    def _best_evaluation(self) -> Evaluation | None:
        return None if self.ok else _best(self.evaluation)

    @property
    def best(self) -> ContactParams | None:
        """The most accurate contact at the given timestep (None when ok)."""
        return None if self._best_evaluation is None else self._best_evaluation.params

    @functools.cached_property
    def best_prediction(self) -> Prediction | None:
        """e of `best` over (and below) the speed range, or None."""
        return None if self.best is None else predict(self.best)

    @functools.cached_property
    def softer(self) -> ContactParams | None:
        """The stiffest contact that meets the target at the given timestep (more
        penetration than asked for), or None."""
        best = self._best_evaluation
        if best is None or not best.resolved or best.w0 >= self.evaluation.w0:
            return None
        edge = largest_passing(
            lambda w0: _resolved(best.request, w0), best.w0, self.evaluation.w0, ratio=1.002
        )
        # a little softer than the edge: the designer asked for that penetration makes the
        # contact 0.5 % stiffer than the bound needs
        for w0 in (max(best.w0, 0.97 * edge), edge):
            ev = _try(best.request, w0)
            if ev is not None and ev.resolved:
                return ev.params
        return best.params

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


def _try(request: Request, w0: float) -> Evaluation | None:
    try:
        return evaluate(request, w0)
    except ContactModelError:
        return None


def _resolved(request: Request, w0: float) -> bool:
    ev = _try(request, w0)
    return ev is not None and ev.resolved


def _best(designed: Evaluation) -> Evaluation | None:
    """The stiffness with the smallest predicted error at dt (golden section in log w0, up to
    four times the designed one)."""
    asked = designed.request
    dt, g, speeds = asked.timestep_s, asked.gravity_mps2, asked.speeds
    w_hi = min(designed.w0 * 4.0, designed.w0dt_max / dt)
    w_lo = w_hi * 1e-4 if g <= 0.0 else max(g / (0.3 * float(speeds.min())), w_hi * 1e-4)
    if w_lo >= w_hi:
        return None

    def cost(lw: float) -> float:
        ev = _try(asked, math.exp(lw))
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
    return _try(asked, math.exp(c if fc <= fd else d))
