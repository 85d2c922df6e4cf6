"""The thresholds behind the report's findings, and the words they choose.

A sentence of the report that states a finding (conserved, constant, drift, loss) is chosen
here by a named threshold on the number it quotes and on the run's conditions (its
integrator, what else touched the bodies); a quantity that is not defined (None, NaN) is
left out with the reason, never formatted. docs/analysis.md lists every threshold and why.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable, Iterator
from typing import Any, ParamSpec, TypeGuard, TypeVar

import polars as pl

from impactlab.physics import SEMI_IMPLICIT  # MuJoCo's semi-implicit integrators
from impactlab.text import md_text

MOMENTUM_CONSERVED_REL = 1e-6
"""Relative momentum change |p' - p| / (|m1 v1| + |m2 v2|) below which momentum is called
conserved. MuJoCo's contact forces on two bodies are equal and opposite, so an isolated pair
keeps its momentum to rounding (1e-16 .. 1e-14 in the collision experiments); a change above
1e-6 is an impulse from something else (gravity, another contact, a constraint)."""

E_CONSTANT_SPREAD = 0.02
"""Spread (max - min) of e over a body's complete bounces on one surface below which e is
called constant across bounces (and between drop heights): twice the third decimal the
report quotes e with, well above the 1e-15 by which e depends on the logging rate."""

E_KNOB_SPREAD = 0.05
"""Spread of the collision e over a parameter sweep below which e is called independent of
the swept parameter."""

APPROACH_FRACTION = 0.1
"""A sweep approaches the elastic answer when its closest v1' is within this fraction of
|v1'_elastic|."""

DRIFT_FACTOR = 2.0
"""A flight's energy drift is explained by the integrator when it has the predicted sign and
lies within this factor of the prediction m g^2 dt T / 2 (either way): the formula holds to
rounding for bodies that do not turn; a body that tumbles, or a model with forces the
analysis does not follow (fluid drag, joints, actuators), departs from it by more."""

NEGLIGIBLE_ENERGY_J = 1e-9
"""An energy (or a change of it) at or below this many joules, or 1e-9 of the initial
energy, is zero for the report: the analysis' energy agrees with MuJoCo's own to 1e-9 J."""

PERCENT_MAX = 1.05
"""A change is written as a fraction of the initial energy only up to 105 % of it: a loss a
little above 100 % is a body resting a fraction of a millimetre inside the soft contact,
below its zero of potential energy; beyond that the initial energy is too small a reference
to be read, and the change is written in joules."""

HIDDEN_PARTS_J = 1e-6
"""When MuJoCo's total energy differs from the analysis' (every logged body and the joints'
rotor and spring energy) by more than this, the model has parts the analysis does not
follow (in logs written before every moving body was logged: a hinged arm, a slider),
which may touch or pull the bodies without a contact the analysis sees."""


def method_line() -> str:
    """The report's Method bullet on how findings are worded, with the thresholds' values."""
    return (
        "**Findings** (conserved, constant, a drift the integrator explains) are chosen by "
        "stated thresholds on the numbers quoted: momentum is conserved below "
        f"{MOMENTUM_CONSERVED_REL:g} relative change for a pair nothing else touched; e is "
        f"constant when its spread is below {E_CONSTANT_SPREAD:g}; a flight drift is the "
        f"integrator's within a factor {DRIFT_FACTOR:g} of m g^2 dt T / 2 for the semi-implicit "
        f"integrators ({', '.join(SEMI_IMPLICIT)}; RK4 has none); energies below "
        f"{NEGLIGIBLE_ENERGY_J:g} J are zero; percentages of the initial energy only up to "
        f"{PERCENT_MAX * 100:.0f} % (docs/analysis.md lists every threshold)."
    )


def defined(x: Any) -> TypeGuard[float]:
    """Whether `x` is a finite number (not None, NaN or infinite)."""
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def num(x: Any, fmt: str = ".3g", unit: str = "") -> str:
    """`x` formatted with its unit; call only for a defined value (`defined`)."""
    return f"{format(x, fmt)}{' ' + unit if unit else ''}"


def span(values: Iterable[Any], fmt: str = ".3g", unit: str = "") -> str | None:
    """The range of the defined values in words ("0.5-0.9 m/s", "from -2.1 % to -0.5 %",
    one value when all read the same); None when no value is defined."""
    xs = [x for x in values if defined(x)]
    if not xs:
        return None
    lo, hi = num(min(xs), fmt), num(max(xs), fmt)
    tail = f" {unit}" if unit else ""
    if lo == hi:
        return f"{lo}{tail}"
    if min(xs) < 0:
        return f"from {lo}{tail} to {hi}{tail}"
    return f"{lo}-{hi}{tail}"


def negligible(x: float, reference: Any = None) -> bool:
    """Whether the energy `x` (J) is zero for the report (`NEGLIGIBLE_ENERGY_J`)."""
    scale = abs(reference) if defined(reference) else 0.0
    return abs(x) <= max(NEGLIGIBLE_ENERGY_J, NEGLIGIBLE_ENERGY_J * scale)


def of_initial(change: Any, initial: Any, fmt: str = ".1f") -> str:
    """An energy change (J) as a percentage of the initial energy, or in joules with the
    reason when the initial energy is zero or the percentage would exceed `PERCENT_MAX`."""
    if not defined(change):
        return "not measured"
    joules = f"{change:.4g} J"
    if not defined(initial):
        return f"{joules} (the initial energy is not known, so no percentage)"
    if negligible(initial):
        return f"{joules} (the initial energy is zero, so no percentage of it)"
    frac = change / initial
    if abs(frac) > PERCENT_MAX:
        return (
            f"{joules} (more than {PERCENT_MAX * 100:.0f} % of the initial {initial:.3g} J: "
            "too small a reference for a percentage)"
        )
    return f"{frac * 100:{fmt}} % of the initial {initial:.4g} J ({joules})"


def _drift(row: dict[str, Any]) -> Any:
    drift = row.get("flight_drift_J")
    return drift if defined(drift) else row.get("flight_drift_max_J")


def drift_kind(row: dict[str, Any]) -> str:
    """A runs-table row's largest flight drift: "none" (no flight), "negligible" (below
    `NEGLIGIBLE_ENERGY_J`), "integrator" (the semi-implicit drift, within `DRIFT_FACTOR`)
    or "unexplained" (RK4, a gain, beyond the factor, or no prediction)."""
    drift = _drift(row)
    if not defined(drift):
        return "none"
    if negligible(drift, row.get("energy_initial_J")):
        return "negligible"
    predicted = row.get("flight_drift_predicted_J")
    if row.get("integrator") not in SEMI_IMPLICIT or not defined(predicted) or not predicted:
        return "unexplained"
    ratio = drift / predicted
    return "integrator" if 1.0 / DRIFT_FACTOR <= ratio <= DRIFT_FACTOR else "unexplained"


def drift_finding(row: dict[str, Any]) -> str:
    """What a run's largest flight drift is, and whether its integrator explains it.

    Reads `flight_drift_J` (signed, the flight with the largest |drift|; else
    `flight_drift_max_J`), `flight_drift_predicted_J` (the integrator's prediction for that
    flight), `integrator` and `energy_initial_J` of a runs-table row.
    """
    kind, drift = drift_kind(row), _drift(row)
    if kind == "none":
        return "no flight phase to test conservation on"
    integrator = row.get("integrator") or "an unrecorded integrator"
    predicted = row.get("flight_drift_predicted_J")
    size = of_initial(drift, row.get("energy_initial_J"), ".3g")
    if kind == "negligible":
        return (
            f"the total energy is conserved in flight: its largest flight drift is "
            f"{drift:.2g} J, below {NEGLIGIBLE_ENERGY_J:g} J ({integrator})"
        )
    if integrator == "RK4":
        return (
            f"the largest flight drift is {size}; the run used RK4, which has no energy drift "
            "in a free flight under uniform gravity, so the drift is not explained by the "
            "integrator (something else acts in flight)"
        )
    if not defined(predicted) or integrator not in SEMI_IMPLICIT:
        return (
            f"the largest flight drift is {size}; the drift {integrator} predicts is not "
            "known, so it is not explained by the integrator"
        )
    if not predicted:
        return (
            f"the largest flight drift is {size}; without gravity {integrator} has no drift in "
            "a free flight, so it is not explained by the integrator (something else acts in "
            "flight)"
        )
    formula = f"m g^2 dt T / 2 = {abs(predicted):.3g} J"
    if kind == "integrator":
        return (
            f"the largest flight drift is {size}, the semi-implicit drift of {integrator} "
            f"({formula} for that flight, within a factor {DRIFT_FACTOR:g}), not a physical loss"
        )
    if drift > 0:
        how = f"a gain, where {integrator}'s semi-implicit step predicts a loss of {formula}"
    else:
        how = (
            f"{drift / predicted:.3g} times the loss of {formula} that {integrator}'s "
            "semi-implicit step predicts"
        )
    return (
        f"the largest flight drift is {size}, {how} for that flight: not explained by the "
        "integrator (something else acts in flight)"
    )


def spread_finding(spread: float) -> str:
    """Whether e is constant across bounces, given its spread (max - min)."""
    if spread < E_CONSTANT_SPREAD:
        return f"constant (spread {spread:.3f}, below {E_CONSTANT_SPREAD:g})"
    return f"not constant: it varies by {spread:.3f} (max - min, above {E_CONSTANT_SPREAD:g})"


def momentum_kind(col: dict[str, Any], run: dict[str, Any] | None = None) -> str:
    """One collision's momentum: "unmeasured", "conserved" (below `MOMENTUM_CONSERVED_REL`,
    nothing else acting), "untested" (below it, but the pair is not isolated or the tables
    cannot tell) or "not conserved"."""
    rel = col.get("momentum_rel_change")
    if not defined(rel):
        return "unmeasured"
    if rel >= MOMENTUM_CONSERVED_REL:
        return "not conserved"
    others, unknown = _acting(col, run)
    return "untested" if others or unknown else "conserved"


def _acting(col: dict[str, Any], run: dict[str, Any] | None) -> tuple[list[str], bool]:
    """What else acted on a collision's pair (in words), and whether the tables cannot tell."""
    others = []
    touched = col.get("touched_by")
    if touched:
        others.append(f"{md_text(touched)} touched the pair during the collision")
    gravity = col.get("gravity_impulse_rel")
    if defined(gravity) and gravity >= MOMENTUM_CONSERVED_REL:
        others.append(
            f"gravity's impulse over the contact, (m1 + m2) g dt, is {gravity:.2g} times "
            "|m1 v1| + |m2 v2|"
        )
    hidden = (run or {}).get("mujoco_diff_max_J")
    if defined(hidden) and hidden > HIDDEN_PARTS_J:
        others.append(
            f"the model has moving parts the analysis does not follow (MuJoCo's energy "
            f"differs from the logged bodies' by {hidden:.3g} J)"
        )
    return others, touched is None or not defined(gravity)


RUN_FIELDS = ("mujoco_diff_max_J",)
"""The runs-table columns `momentum_kind` and `momentum_finding` read of a collision's run."""


def momentum_runs(runs: pl.DataFrame | None, collisions: pl.DataFrame) -> dict[str, dict[str, Any]]:
    """The row of each run that has a collision in `collisions`, as `momentum_kind` and
    `momentum_finding` read it (run id -> those of RUN_FIELDS the table has): a few numbers
    per colliding run, not every column of every run."""
    if runs is None or collisions.is_empty():
        return {}
    fields = [c for c in RUN_FIELDS if c in runs.columns]
    mine = runs.filter(pl.col("run_id").is_in(collisions["run_id"].unique().implode()))
    return {
        r["run_id"]: {c: r[c] for c in fields}
        for r in mine.select("run_id", *fields).iter_rows(named=True)
    }


def momentum_finding(col: dict[str, Any], run: dict[str, Any] | None = None) -> str:
    """Whether one collision conserves momentum, in words: its relative change against
    `MOMENTUM_CONSERVED_REL` and what else acted on the pair (`touched_by`,
    `gravity_impulse_rel` of the collisions table; the run's `mujoco_diff_max_J`)."""
    kind = momentum_kind(col, run)
    if kind == "unmeasured":
        return "the momentum change is not measured (no state before or after the contact)"
    rel = col["momentum_rel_change"]
    others, _ = _acting(col, run)
    threshold = f"{MOMENTUM_CONSERVED_REL:g}"
    if kind == "conserved":
        return (
            f"momentum is conserved: it changes by {rel:.2g} (relative, below {threshold}) "
            "and nothing else touched the pair"
        )
    if kind == "untested":
        if others:
            return (
                f"momentum changes by {rel:.2g} (relative, below {threshold}), but the pair is "
                "not isolated (" + "; ".join(others) + "), so this does not test conservation"
            )
        return (
            f"momentum changes by {rel:.2g} (relative, below {threshold}); the tables do not "
            "say whether anything else acted on the pair, so conservation is not claimed"
        )
    why = (
        "; ".join(others)
        if others
        else "no other contact the log shows touched the pair, so the cause is not in the log "
        "(a constraint, a joint or an actuator)"
    )
    head = f"momentum is not conserved: it changes by {rel:.2g} (relative, above {threshold})"
    return f"{head}: {why}"


def elastic_gap(v1_after: Iterable[Any], v1_elastic: Any) -> float | None:
    """The smallest |v1' - v1'_elastic| / |v1'_elastic| over a sweep's runs; None when the
    elastic answer is not defined (an eccentric impact) or zero (no fraction of it)."""
    if not defined(v1_elastic) or abs(v1_elastic) < 1e-12:
        return None
    gaps = [abs(v - v1_elastic) / abs(v1_elastic) for v in v1_after if defined(v)]
    return min(gaps) if gaps else None


WORDING_ERRORS: tuple[type[Exception], ...] = (
    TypeError,
    ValueError,
    ArithmeticError,
    LookupError,
    pl.exceptions.PolarsError,
)
"""The faults a sentence builder can hit on numbers it did not expect (a None formatted, a
missing column): caught per run (`each`) or per answer (`guard_lines`, `guard_line`)."""


def _failed(what: str, exc: Exception) -> str:
    return f"{what}: this finding could not be worded ({type(exc).__name__}: {exc})."


def each(
    rows: Iterable[dict[str, Any]], sentence: Callable[[dict[str, Any]], str]
) -> Iterator[str]:
    """`sentence` of each row, made as it is read; a row whose sentence fails gets a sentence
    naming it and the error, so a fault in one run's wording stays that run's and the report
    is still written."""
    for r in rows:
        try:
            yield sentence(r)
        except WORDING_ERRORS as exc:
            yield _failed(str(r.get("run") or r.get("run_id") or "a run"), exc)


def guard_lines(
    what: str,
) -> Callable[[Callable[..., Iterable[str]]], Callable[..., Iterator[str]]]:
    """Decorate an answer builder (sentences, as a list or made one by one): the answer is
    made as it is read (a sweep's answer of one sentence per run is never held whole), and a
    fault becomes one sentence naming `what` and the error instead of ending the whole
    analysis (after the sentences made before it)."""

    def wrap(build: Callable[..., Iterable[str]]) -> Callable[..., Iterator[str]]:
        @functools.wraps(build)
        def guarded(*args: Any, **kwargs: Any) -> Iterator[str]:
            try:
                yield from build(*args, **kwargs)
            except WORDING_ERRORS as exc:
                yield _failed(what, exc)

        return guarded

    return wrap


P = ParamSpec("P")
Answer = TypeVar("Answer", str, str | None)


def guard_line(what: str) -> Callable[[Callable[P, Answer]], Callable[P, Answer]]:
    """Decorate a headline builder (one answer): a fault becomes "Not answered" with `what`
    and the error instead of ending the whole analysis."""

    def wrap(build: Callable[P, Answer]) -> Callable[P, Answer]:
        @functools.wraps(build)
        def guarded(*args: P.args, **kwargs: P.kwargs) -> Answer:
            try:
                return build(*args, **kwargs)
            except WORDING_ERRORS as exc:
                return "Not answered: " + _failed(what, exc)

        return guarded

    return wrap
