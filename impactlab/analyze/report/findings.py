"""Thresholds that choose the report's words (docs/analysis.md), and the findings they choose."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any, TypeGuard

import polars as pl

from impactlab.analyze.measure.summary import NEGLIGIBLE_ENERGY_J
from impactlab.analyze.report.blocks import quantity
from impactlab.physics import SEMI_IMPLICIT
from impactlab.show import count, number

MOMENTUM_CONSERVED_REL = 1e-6
"""Relative momentum change |p' - p| / (|m1 v1| + |m2 v2|) below which it is conserved."""
E_CONSTANT_SPREAD = 0.02
"""Spread (max - min) of e over bounces or drop heights below which e is constant."""
E_TARGET_TOLERANCE = 0.01
"""A measured e this close to its target e(v) at its speed follows it (the designer promises
0.005 for a constant e, 0.01 for a curve: docs/contact-model.md)."""
E_KNOB_SPREAD = 0.05
"""Spread of the collision e over a sweep below which e does not depend on the knob."""
APPROACH_FRACTION = 0.1
"""A sweep approaches the elastic answer when its closest v1' is this close to it (relative)."""
DRIFT_FACTOR = 2.0
"""A flight drift is the integrator's within this factor of m g^2 dt T / 2, either way."""
PERCENT_MAX = 1.05
"""A change is a percentage of the initial energy only up to this fraction of it."""
HIDDEN_PARTS_J = 1e-6
"""MuJoCo's energy above the bodies' by more than this: the model has parts not followed."""


def method_sentence() -> str:
    """How findings are worded, with the thresholds' values."""
    return (
        "Findings (conserved, constant, a drift the integrator explains) are chosen by stated "
        f"thresholds on the numbers quoted: momentum is conserved below {number(1e-6)} "
        "relative change for a pair nothing else touched; e is constant when its spread is "
        f"below {E_CONSTANT_SPREAD:g}; a flight drift is the integrator's within a factor "
        f"{DRIFT_FACTOR:g} of m g² dt T / 2 for the semi-implicit integrators "
        f"({', '.join(SEMI_IMPLICIT)}; RK4 has none); energies below {number(1e-9)} J are "
        f"zero; percentages of the initial energy only up to {PERCENT_MAX * 100:.0f} %."
    )


def defined(x: Any) -> TypeGuard[float]:
    """Whether `x` is a finite number (not None, NaN or infinite)."""
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def negligible(x: float, reference: Any = None) -> bool:
    """Whether the energy `x` (J) is zero for the report (`NEGLIGIBLE_ENERGY_J`)."""
    scale = abs(reference) if defined(reference) else 0.0
    return abs(x) <= max(NEGLIGIBLE_ENERGY_J, NEGLIGIBLE_ENERGY_J * scale)


def share(change: Any, initial: Any) -> float | None:
    """`change` as a fraction of `initial`, when that reads (`PERCENT_MAX`), else None."""
    if not defined(change) or not defined(initial) or negligible(initial):
        return None
    frac = change / initial
    return frac if abs(frac) <= PERCENT_MAX else None


def drift(row: dict[str, Any]) -> Any:
    """A runs-table row's largest flight drift, J (signed when known)."""
    value = row.get("flight_drift_J")
    return value if defined(value) else row.get("flight_drift_max_J")


def drift_kind(row: dict[str, Any]) -> str:
    """A run's largest flight drift: "none" (no flight), "negligible" (`NEGLIGIBLE_ENERGY_J`),
    "integrator" (the semi-implicit drift, within `DRIFT_FACTOR` of its prediction),
    "residual" (no free-flight formula holds: jointed bodies or other forces; what the budget
    leaves, the integrator's) or "unexplained" (RK4, a gain, beyond the factor)."""
    value = drift(row)
    if not defined(value):
        return "none"
    if negligible(value, row.get("energy_initial_J")):
        return "negligible"
    predicted = row.get("flight_drift_predicted_J")
    if predicted is None:  # no free-flight formula for this run: the budget's residual
        return "residual"
    if row.get("integrator") not in SEMI_IMPLICIT or not defined(predicted) or not predicted:
        return "unexplained"
    return "integrator" if 1 / DRIFT_FACTOR <= value / predicted <= DRIFT_FACTOR else "unexplained"


DRIFT_WORDS = {
    "none": "no flight",
    "negligible": "conserved",
    "integrator": "integrator's drift",
    "residual": "integrator's residual",
    "unexplained": "not explained",
}


def drift_finding(row: dict[str, Any]) -> str:
    """Why a run's flight drift is not the integrator's (a sentence; `drift_kind` "unexplained")."""
    value, predicted = drift(row), row.get("flight_drift_predicted_J")
    integrator = row.get("integrator") or "an unrecorded integrator"
    if integrator == "RK4":
        why = "RK4 has no energy drift in a free flight, so something else acts in flight"
    elif not defined(predicted) or integrator not in SEMI_IMPLICIT:
        why = f"the drift {integrator} predicts is not known"
    elif not predicted:
        why = f"without gravity {integrator} has no drift in flight: something else acts"
    else:
        formula = f"m g² dt T / 2 = {quantity(abs(predicted), 'J')}"
        how = "a gain" if value > 0 else f"{number(value / predicted)} times the predicted loss"
        why = f"it is {how} ({formula}): something else acts in flight"
    size = quantity(value, "J")
    return f"The largest flight drift, {size}, is not explained by the integrator: {why}."


def momentum_kind(col: dict[str, Any], run: dict[str, Any] | None = None) -> str:
    """One collision's momentum: "unmeasured", "conserved" (below `MOMENTUM_CONSERVED_REL`,
    nothing else acting), "untested" (below it, but the pair is not isolated or the tables
    cannot tell) or "not conserved"."""
    rel = col.get("momentum_rel_change")
    if not defined(rel):
        return "unmeasured"
    if rel >= MOMENTUM_CONSERVED_REL:
        return "not conserved"
    others, unknown = acting(col, run)
    return "untested" if others or unknown else "conserved"


def acting(col: dict[str, Any], run: dict[str, Any] | None) -> tuple[list[str], bool]:
    """What else acted on a collision's pair (in words), and whether the tables cannot tell."""
    others = []
    touched = col.get("touched_by")
    if touched:
        others.append(f"{touched} touched the pair during the collision")
    gravity = col.get("gravity_impulse_rel")
    if defined(gravity) and gravity >= MOMENTUM_CONSERVED_REL:
        others.append(f"gravity's impulse over the contact is {number(gravity, 2)} of the momentum")
    hidden = (run or {}).get("mujoco_diff_max_J")
    if defined(hidden) and hidden > HIDDEN_PARTS_J:
        others.append(
            "the model has moving parts the analysis does not follow (MuJoCo's energy differs "
            f"from the logged bodies' by {quantity(hidden, 'J')})"
        )
    return others, touched is None or not defined(gravity)


def momentum_finding(col: dict[str, Any], run: dict[str, Any] | None = None) -> str:
    """Why one collision does not show momentum conserved, in words (`momentum_kind` other
    than "conserved")."""
    kind = momentum_kind(col, run)
    if kind == "unmeasured":
        return "The momentum change is not measured (no state before or after the contact)."
    rel = number(col["momentum_rel_change"], 2)
    others, _ = acting(col, run)
    if kind == "untested":
        why = "; ".join(others) or "the tables do not say whether anything else acted"
        return f"Momentum changes by {rel} (relative), but this does not test conservation: {why}."
    why = "; ".join(others) or "no contact the log shows explains it (a constraint, a joint?)"
    return f"Momentum is not conserved: it changes by {rel} (relative): {why}."


def momentum_words(done: pl.DataFrame, runs: pl.DataFrame) -> tuple[str, list[str]]:
    """Whether the complete collisions `done` conserve momentum, in words ("momentum is
    conserved in all 4 collisions (relative change at most ...)"), and why for each that
    does not show it (`momentum_finding`)."""
    mine = runs.filter(pl.col("run_id").is_in(done["run_id"].unique().implode()))
    by_run = {r["run_id"]: r for r in mine.iter_rows(named=True)}  # what momentum_kind reads
    rows = list(done.iter_rows(named=True))
    kinds = each(rows, lambda c: momentum_kind(c, by_run.get(c["run_id"])))
    top = done.select(pl.col("momentum_rel_change").max()).item()
    n, kept = len(rows), kinds.count("conserved")
    if kept == n:
        most = f"at most {number(top, 2)}, below {number(MOMENTUM_CONSERVED_REL, None)}"
        words = f"momentum is conserved in {'all ' if n > 1 else ''}{count(n, 'collision')}"
        return f"{words} (relative change {most})", []
    up_to = f" (relative change up to {number(top, 2)})" if defined(top) else ""
    odd = [
        momentum_finding(r, by_run.get(r["run_id"]))
        for r, k in zip(rows, kinds, strict=True)
        if k != "conserved"
    ]
    return f"momentum is conserved in {kept} of {n} collisions{up_to}", odd


def elastic_gap(v1_after: Iterable[Any], v1_elastic: Any) -> float | None:
    """The smallest |v1' - v1'_elastic| / |v1'_elastic| over a sweep's runs; None when the
    elastic answer is not defined (an eccentric impact) or zero."""
    if not defined(v1_elastic) or abs(v1_elastic) < 1e-12:
        return None
    gaps = [abs(v - v1_elastic) / abs(v1_elastic) for v in v1_after if defined(v)]
    return min(gaps) if gaps else None


def at_rest(ground: pl.DataFrame) -> list[str]:
    """Why runs that end at rest end early and slightly below zero energy."""
    rest = ground.filter(pl.col("reason") == "bodies at rest")
    if rest.is_empty():
        return []
    r = rest.row(0, named=True)
    out = (
        f"{rest.height} run(s) stop once every body is at rest, {r.get('run') or r['run_id']} at "
        f"{quantity(r['duration_s'], 's')}."
    )
    if defined(r["energy_final_J"]) and r["energy_final_J"] < 0:
        out += (
            f" Its final energy is slightly negative ({quantity(r['energy_final_J'], 'J')}): the "
            "ball rests a fraction of a millimetre into MuJoCo's soft contact, below the "
            "surface where potential energy is zero."
        )
    return [out]


WORDING_ERRORS: tuple[type[Exception], ...] = (
    TypeError,
    ValueError,
    ArithmeticError,
    LookupError,
    pl.exceptions.PolarsError,
)
"""The faults wording can hit on numbers it did not expect (a None formatted, a column
missing): caught per run (`each`) and per question (`report.document`), so one fault costs
one cell or one answer, never the analysis."""


def failed(what: str, exc: Exception) -> str:
    return f"{what}: could not be worded ({type(exc).__name__}: {exc})"


def each(rows: Iterable[dict[str, Any]], word: Callable[[dict[str, Any]], str]) -> list[str]:
    """`word` of each row; a row whose wording fails gets the error instead."""
    out = []
    for r in rows:
        try:
            out.append(word(r))
        except WORDING_ERRORS as exc:
            out.append(failed(str(r.get("run") or r.get("run_id") or "a run"), exc))
    return out
