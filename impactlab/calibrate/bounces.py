"""The multi-bounce case: drops that bounce several times, every bounce measured from the logs.

A ball (radius r, mass m) reaches the floor at ``BOUNCE_SPEED_MPS`` and bounces until
``stop.bounces`` (until about ``LAST_SPEED_MPS``, at most ``MAX_BOUNCES``). Its contact asks
for restitution e over a speed range: the default one the recorder derives from the
experiment (from the first impact down to the last bounce that matters, floored at
``impactlab.contact.SPEED_FLOOR_MPS``) or an explicit ``[v_lo, BOUNCE_SPEED_MPS]``. Each bounce
comes from the analysis stage's bounces table (``e_velocity``, surface to surface):

- in the range, |e - target| <= RESTITUTION_TOLERANCE and the penetration is within the bound;
- below it, gravity lowers e as the designer predicts: the measured e must lie in the band the
  step emulation gives at that impact speed (lowest..highest over contact-onset phases, widened
  by ``BAND_MARGIN``), and the table shows the predicted mean next to the measured value.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Sequence
from typing import Any

import polars as pl

from impactlab.calibrate.grid import (
    GAP_STEPS,
    GRAVITY_MPS2,
    KINDS,
    TIMESTEP_LADDER,
    BounceCase,
    Grid,
    GridPoint,
    _tag,
    grid_points,
)
from impactlab.contact import (
    RESTITUTION_TOLERANCE,
    ContactModelError,
    ContactParams,
    restitution_spread,
)
from impactlab.errors import SpecError
from impactlab.record import plan

BOUNCE_SPEED_MPS = 3.0
LAST_SPEED_MPS = 0.15
MAX_BOUNCES = 8
BAND_MARGIN = 0.001
RANGE_EDGE = 1e-3
"""Relative margin at the ends of a speed range: the first impact is set up to arrive at the
range's top speed, and the analysis measures it at the moment the surfaces meet, up to one
step of gravity faster (g dt / v, below 1e-3 here)."""
PENETRATION_BOUND = 0.02


def n_bounces(e: float) -> int:
    """Bounces until the impact speed falls to about LAST_SPEED_MPS (2 .. MAX_BOUNCES)."""
    n = math.ceil(math.log(LAST_SPEED_MPS / BOUNCE_SPEED_MPS) / math.log(e)) + 1
    return min(MAX_BOUNCES, max(2, n))


def _toml(case: BounceCase, dt: float, name: str) -> str:
    v, g, r = BOUNCE_SPEED_MPS, GRAVITY_MPS2, case.radius
    n = case.bounces or n_bounces(case.target)
    gap = GAP_STEPS * v * dt
    vz0 = -math.sqrt(v * v - 2.0 * g * gap)
    fast = min(case.target + RESTITUTION_TOLERANCE, 1.0)  # the longest flights
    flights = sum(2.0 * v * fast**k / g for k in range(1, n)) + v * fast**n / g
    max_time = gap / v + flights + 0.05
    rng = "" if case.low is None else f"speed_range = [{case.low!r}, {v!r}]\n"
    label = "default range" if case.low is None else f"range {case.low:g}..{v:g} m/s"
    return f"""name = "{name}"
description = "calibration: {n} bounces, target e = {case.target:g}, r = {r:g} m, {label}"

[options]
timestep = {dt!r}
integrator = "{case.integrator}"
gravity = [0.0, 0.0, {-g!r}]

[contact]
restitution = {case.target!r}
{rng}
[bodies.ball]
radius = {r!r}
mass = {float(case.mass)!r}
pos = [0.0, 0.0, {r + gap!r}]
vel = [0.0, 0.0, {vz0!r}]

[stop]
max_time = {max_time!r}
bounces = {n}

[logging]
every = 1
"""


def bounce_point(case: BounceCase) -> GridPoint:
    """The drop's spec at the largest timestep of TIMESTEP_LADDER the recorder accepts.

    Raises:
        ContactModelError: no timestep of the ladder resolves the contact.
    """
    low = "d" if case.low is None else _tag(case.low)
    name = (
        f"cal_bounces_e{_tag(case.target)}_r{_tag(case.radius)}_m{_tag(case.mass)}_lo{low}"
        f"_{case.integrator.lower()}"
    )
    last: Exception | None = None
    for dt in TIMESTEP_LADDER:
        toml = _toml(case, dt, name)
        try:
            (run,) = plan(tomllib.loads(toml))
        except SpecError as exc:
            if "cannot be reached" in str(exc):
                raise ContactModelError(str(exc)) from None
            last = exc
            continue
        (pair,) = run.pairs  # as planned
        return GridPoint(
            name,
            "bounces",
            case.target,
            BOUNCE_SPEED_MPS,
            case.mass,
            None,
            BOUNCE_SPEED_MPS,
            dt,
            pair.params,
            toml,
            radius=case.radius,
        )
    raise ContactModelError(f"{name}: no timestep in {TIMESTEP_LADDER} works: {last}")


def all_points(grid: Grid, kinds: Sequence[str] = KINDS) -> list[GridPoint]:
    """Every point of a grid, multi-bounce drops included, ordered by timestep."""
    points = grid_points(grid, [k for k in kinds if k != "bounces"])
    if "bounces" in kinds:
        points += [bounce_point(case) for case in grid.bounce_cases]
    return sorted(points, key=lambda p: (p.timestep, KINDS.index(p.kind)))


def _band(params: ContactParams, speeds: list[float]) -> tuple[list[float], ...]:
    if not speeds:
        return [], [], []
    mean, lo, hi = restitution_spread(
        params, impact_speed_mps=speeds, gravity_mps2=GRAVITY_MPS2, timestep_s=params.timestep_s
    )
    return list(mean), list(lo), list(hi)


def bounce_table(
    points: Sequence[GridPoint], runs: pl.DataFrame, bounces: pl.DataFrame
) -> pl.DataFrame:
    """One row per measured bounce of every multi-bounce run: measured against target or
    against the prediction below the range, and whether it meets its bound."""
    run_of = dict(zip(runs["experiment"], runs["run_id"], strict=True)) if runs.height else {}
    rows = []
    for p in (q for q in points if q.kind == "bounces"):
        lo, hi = p.params.speed_range_mps
        b = bounces.filter((pl.col("run_id") == run_of.get(p.name)) & pl.col("complete"))
        speeds = [-v for v in b["v_in_mps"].to_list()]
        mean, low, high = _band(p.params, speeds)
        for i, d in enumerate(b.sort("bounce").iter_rows(named=True)):
            v = speeds[i]
            inside = bool(lo * (1.0 - RANGE_EDGE) <= v <= hi * (1.0 + RANGE_EDGE))
            e = d["e_velocity"]
            pen = d["max_penetration_m"] / p.radius
            ok = bool(
                abs(e - p.target) <= RESTITUTION_TOLERANCE and pen <= PENETRATION_BOUND
                if inside
                else low[i] - BAND_MARGIN <= e <= high[i] + BAND_MARGIN
            )
            rows.append(
                {
                    "name": p.name,
                    "target": p.target,
                    "radius_m": p.radius,
                    "mass_kg": p.m1,
                    "integrator": p.params.integrator,
                    "range_lo_mps": lo,
                    "range_hi_mps": hi,
                    "timestep_s": p.timestep,
                    "bounce": d["bounce"],
                    "v_in_mps": v,
                    "e_measured": e,
                    "error": e - p.target,
                    "in_range": inside,
                    "e_predicted": float(mean[i]),
                    "e_predicted_lowest": float(low[i]),
                    "e_predicted_highest": float(high[i]),
                    "penetration_frac": pen,
                    "ok": ok,
                }
            )
    return pl.DataFrame(rows, infer_schema_length=None)


def prediction_curves(points: Sequence[GridPoint], n: int = 24) -> pl.DataFrame:
    """The designer's mean e over impact speeds (0.05 m/s .. the first impact) per drop.

    Returns:
        (name, speed_mps, e_predicted); empty without multi-bounce drops.
    """
    rows = []
    for p in (q for q in points if q.kind == "bounces"):
        speeds = [0.05 * (BOUNCE_SPEED_MPS / 0.05) ** (i / (n - 1)) for i in range(n)]
        mean, _, _ = _band(p.params, speeds)
        rows += [(p.name, v, e) for v, e in zip(speeds, mean, strict=True)]
    schema = {"name": pl.String, "speed_mps": pl.Float64, "e_predicted": pl.Float64}
    return pl.DataFrame(rows, schema=schema, orient="row")


def summarize_bounces(frame: pl.DataFrame, points: Sequence[GridPoint]) -> dict[str, Any] | None:
    """Runs, bounces in and below the range, the worst of each, failures (JSON-ready)."""
    runs = [p for p in points if p.kind == "bounces"]
    if not runs:
        return None
    inside = frame.filter(pl.col("in_range")) if frame.height else frame
    below = frame.filter(~pl.col("in_range")) if frame.height else frame
    worst = None
    if inside.height:
        w = inside.sort(pl.col("error").abs()).row(-1, named=True)
        worst = {k: w[k] for k in ("name", "bounce", "v_in_mps", "e_measured", "error")}
    measured = {r for r in frame["name"].to_list()} if frame.height else set()
    return {
        "runs": len(runs),
        "runs_without_bounces": sorted(p.name for p in runs if p.name not in measured),
        "bounces": frame.height,
        "in_range": inside.height,
        "max_abs_error_in_range": _largest(inside, pl.col("error").abs()),
        "worst_in_range": worst,
        "below_range": below.height,
        "max_abs_diff_predicted_below": _largest(
            below, (pl.col("e_measured") - pl.col("e_predicted")).abs()
        ),
        "max_penetration_frac_in_range": _largest(inside, pl.col("penetration_frac")),
        "failures": frame.filter(~pl.col("ok")).to_dicts() if frame.height else [],
    }


def column_max(frame: pl.DataFrame, values: pl.Expr) -> float:
    """The largest of `values` over `frame`, NaN left out; 0 when there is none."""
    return float(frame.select(values.drop_nans().max()).item() or 0.0)


def _largest(frame: pl.DataFrame, values: pl.Expr) -> float | None:
    """The largest of `values` over `frame`; None for no rows."""
    return float(frame.select(values.max()).item()) if frame.height else None


def report_lines(frame: pl.DataFrame, summary: dict[str, Any] | None) -> list[str]:
    """calibration.md's section on the multi-bounce drops."""
    if not summary or not frame.height:
        return []
    lines = [
        "## Every bounce of a drop",
        "",
        f"{summary['runs']} drops reaching the floor at {BOUNCE_SPEED_MPS:g} m/s and bouncing "
        f"until about {LAST_SPEED_MPS:g} m/s (at most {MAX_BOUNCES} bounces, or the count a case "
        "asks for). Each contact "
        "holds e over its speed range (the default from the experiment, or the range shown); "
        f"every bounce in the range must be within {RESTITUTION_TOLERANCE} of the target. "
        "Below the range gravity lowers e; the designer's prediction at that impact speed "
        "(step emulation, mean and the lowest..highest over where in a step the contact "
        "begins) is shown next to the measurement.",
        "",
        f"In the range: {summary['in_range']} bounces, max |e - target| "
        f"**{summary['max_abs_error_in_range'] or 0:.4f}**, max penetration "
        f"{summary['max_penetration_frac_in_range'] or 0:.2%} of the radius. Below the range: "
        f"{summary['below_range']} bounces, max |measured - predicted| "
        f"{summary['max_abs_diff_predicted_below'] or 0:.4f}. "
        f"{len(summary['failures'])} bounce(s) miss their bound.",
        "",
        "| target | radius (m) | mass (kg) | integrator | range (m/s) | bounce | impact (m/s) "
        "| e measured | error | predicted (band) | ok |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for d in frame.iter_rows(named=True):
        where = "" if d["in_range"] else "below: "
        lines.append(
            f"| {d['target']:g} | {d['radius_m']:g} | {d['mass_kg']:g} | {d['integrator']} | "
            f"{d['range_lo_mps']:.3g}..{d['range_hi_mps']:.3g} | {d['bounce']} | "
            f"{d['v_in_mps']:.3f} | {d['e_measured']:.4f} | {d['error']:+.4f} | {where}"
            f"{d['e_predicted']:.4f} ({d['e_predicted_lowest']:.4f}.."
            f"{d['e_predicted_highest']:.4f}) | {'yes' if d['ok'] else '**no**'} |"
        )
    return [*lines, ""]
