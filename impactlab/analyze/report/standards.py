"""The ball sports' drop tests (docs/analysis.md cites each rule) as pass/fail bands of e."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import polars as pl

from impactlab.analyze.report.context import RunBrief

DROP_MATCH = 0.01
"""A run's drop height (its first fall, bottom of the ball to the surface) is the test's
when within this fraction of it."""


@dataclass(frozen=True)
class DropTest:
    """A rule: a ball of this mass (kg) and diameter (m) dropped from `drop_m` onto a rigid
    surface rebounds `rebound_m` (lo, hi), both heights of the ball's bottom over the surface.
    Without air (MuJoCo has none), a rebound h from a drop H is e = sqrt(h / H), at the
    impact speed sqrt(2 g H)."""

    name: str
    mass_kg: tuple[float, float]
    diameter_m: tuple[float, float]
    drop_m: float
    rebound_m: tuple[float, float]

    @property
    def band(self) -> tuple[float, float]:
        """The e the ball must have: (lowest, highest)."""
        lo, hi = (math.sqrt(h / self.drop_m) for h in self.rebound_m)
        return lo, hi

    def fits(self, mass_kg: float, radius_m: float | None) -> bool:
        """Whether a ball of this mass and radius is the rule's ball."""
        if radius_m is None:
            return False
        (m_lo, m_hi), (d_lo, d_hi) = self.mass_kg, self.diameter_m
        return m_lo <= mass_kg <= m_hi and d_lo <= 2 * radius_m <= d_hi


NEAR = 0.02
"""A ball whose rule gives one mass and diameter is the rule's within this fraction of them."""

DROP_TESTS = (
    # ITF Rules of Tennis, Appendix I (the ball), b and c: mass "more than 1.975 ounces (56.0
    # grams) and less than 2.095 ounces (59.4 grams)", size 6.541-6.858 cm (types 1 and 2),
    # "a bound of more than 53 inches (134.62 cm) and less than 58 inches (147.32 cm) when
    # dropped 100 inches (254.00 cm) upon a flat, rigid surface e.g. concrete"
    DropTest("ITF tennis ball", (0.0560, 0.0594), (0.06541, 0.06858), 2.54, (1.3462, 1.4732)),
    # ITTF Technical Leaflet T3 (the ball), B.7: "rebound to a height of not less than 240mm
    # and not more than 265mm when dropped from a height of 305mm on to a standard steel
    # block" (non-celluloid balls), heights of the ball's bottom; ITTF Laws 2.3.1-2.3.2: a
    # diameter of 40 mm, a weight of 2.7 g
    DropTest(
        "ITTF table tennis ball",
        (0.0027 * (1 - NEAR), 0.0027 * (1 + NEAR)),
        (0.040 * (1 - NEAR), 0.040 * (1 + NEAR)),
        0.305,
        (0.240, 0.265),
    ),
)
"""The drop tests whose rule text docs/analysis.md quotes and cites (no source, no test)."""


def balls(briefs: Iterable[RunBrief]) -> dict[str, tuple[float, float | None]]:
    """run_id -> (mass kg, radius m) of each run of one body."""
    return {b.run_id: (b.masses[0], b.radii[0]) for b in briefs if len(b.radii) == 1}


def drop_tests(bounces: pl.DataFrame, balls: dict[str, tuple[float, float | None]]) -> pl.DataFrame:
    """Each first bounce of a rule's ball dropped from the rule's height, judged by its
    measured e (from velocities): run_id, test, drop_m, speed_mps, e, lo, hi, passed.

    Args:
        bounces: the bounces table (first falls: `bounce` 1 with `apex_before_m`).
        balls: run_id -> (mass kg, radius m) of a run with one body (`balls`).
    """
    rows = []
    needed = {"bounce", "complete", "e_velocity", "apex_before_m", "v_in_mps"}
    if needed <= set(bounces.columns):
        done = pl.col("complete") & pl.col("e_velocity").is_not_null()
        for b in bounces.filter((pl.col("bounce") == 1) & done).iter_rows(named=True):
            mass, radius = balls.get(b["run_id"], (math.nan, None))
            e, drop = b["e_velocity"], b["apex_before_m"] or math.nan
            rows += [
                (b["run_id"], t.name, drop, -b["v_in_mps"], e, *t.band, t.band[0] <= e <= t.band[1])
                for t in DROP_TESTS
                if t.fits(mass, radius) and abs(drop - t.drop_m) <= DROP_MATCH * t.drop_m
            ]
    names = ("run_id", "test", "drop_m", "speed_mps", "e", "lo", "hi", "passed")
    kinds = (pl.String, pl.String, *[pl.Float64] * 5, pl.Boolean)
    return pl.DataFrame(rows, schema=dict(zip(names, kinds, strict=True)), orient="row")
