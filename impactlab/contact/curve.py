"""A target restitution that depends on the impact speed: measured points e(v)."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from impactlab.contact.closed_form import RESTITUTION_FLOOR, ContactModelError, checked
from impactlab.physics import restitution_on_curve

MAX_POINTS = 64
"""The most points a curve may have."""


@dataclass(frozen=True)
class RestitutionCurve:
    """A target e(v): points (normal impact speed in m/s, ascending; e), piecewise linear in
    speed between them; no target outside them. Build it with :meth:`of`."""

    speed_mps: tuple[float, ...]
    e: tuple[float, ...]

    @classmethod
    def of(cls, speed_mps: Sequence[float], e: Sequence[float]) -> RestitutionCurve:
        """A checked curve.

        Raises:
            ContactModelError: not two sequences of the same length (2..MAX_POINTS), speeds
                not strictly ascending or outside the designer's limits, an e outside
                RESTITUTION_FLOOR..1.
        """
        try:
            speeds, es = list(speed_mps), list(e)
        except TypeError:
            raise ContactModelError(
                f"a restitution curve is two lists, speed_mps and e, got {speed_mps!r}, {e!r}"
            ) from None
        if len(speeds) != len(es) or not 2 <= len(speeds) <= MAX_POINTS:
            raise ContactModelError(
                f"a restitution curve needs 2..{MAX_POINTS} speeds and as many e, got "
                f"{len(speeds)} speeds and {len(es)} e"
            )
        xs = tuple(checked(f"speed_mps[{i}]", v, "speed") for i, v in enumerate(speeds))
        if any(b <= a for a, b in itertools.pairwise(xs)):
            raise ContactModelError(f"speed_mps must be strictly ascending, got {list(xs)}")
        ys = []
        for i, value in enumerate(es):
            try:
                y = float(value)
            except (TypeError, ValueError):
                y = math.nan
            if not RESTITUTION_FLOOR <= y <= 1.0:
                raise ContactModelError(
                    f"e[{i}] must be a number in {RESTITUTION_FLOOR:.4g}..1, got {value!r}"
                )
            ys.append(y)
        return cls(xs, tuple(ys))

    @property
    def span_mps(self) -> tuple[float, float]:
        """(lowest, highest) speed in m/s: where the curve promises a target."""
        return self.speed_mps[0], self.speed_mps[-1]

    def at(self, speed_mps: float | Sequence[float] | np.ndarray) -> np.ndarray:
        """The target e at speeds in m/s (NaN outside the span)."""
        return restitution_on_curve(speed_mps, self.speed_mps, self.e)


LAW_POINTS = 17
"""Points a law is tabulated at (geometrically spaced): piecewise linear between them, the
Ramirez law is followed to about 2e-4."""


def ramirez_curve(c1: float, c2: float, speed_range_mps: Sequence[float]) -> RestitutionCurve:
    """The viscoelastic spheres' e(v) = 1 - c1 v^(1/5) + c2 v^(2/5) (Ramirez, Poeschel,
    Brilliantov and Schwager, Phys. Rev. E 60, 4465 (1999); v in m/s), tabulated at
    LAW_POINTS speeds over (lo, hi).

    Raises:
        ContactModelError: coefficients not numbers, a range not 0 < lo < hi, or an e
            outside RESTITUTION_FLOOR..1 in it.
    """
    try:
        lo, hi = (float(v) for v in speed_range_mps)
        a, b = float(c1), float(c2)
    except (TypeError, ValueError):
        raise ContactModelError(
            f"a law needs two coefficients and a range lo..hi, got {c1!r}, {c2!r}, "
            f"{speed_range_mps!r}"
        ) from None
    if not (math.isfinite(a) and math.isfinite(b) and 0.0 < lo < hi):
        raise ContactModelError(
            f"a law needs finite coefficients and 0 < lo < hi, got C1 {c1!r}, C2 {c2!r}, "
            f"{lo:g}..{hi:g} m/s"
        )
    speeds = np.geomspace(lo, hi, LAW_POINTS)
    return RestitutionCurve.of(speeds.tolist(), (1.0 - a * speeds**0.2 + b * speeds**0.4).tolist())
