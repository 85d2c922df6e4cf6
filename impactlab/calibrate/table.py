"""Target against measured e at every impact of a calibrated pair, from the analysis' tables."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import polars as pl

from impactlab.contact import RESTITUTION_TOLERANCE, restitution_spread

if TYPE_CHECKING:
    from impactlab.record import PlannedRun

BAND_MARGIN = 0.001
"""How far outside the designer's predicted band a single impact outside the speed range may
lie: the band spans 64 contact-onset phases at that speed, an impact may begin between them."""
PENETRATION_MARGIN = 1.01
"""The measured penetration against the designer's worst case at the top speed: 1 % for the
interpolation of its table."""
SCHEMA = pl.Schema(
    {
        "run_id": pl.String,
        "pair": pl.String,
        "impact": pl.Int64,
        "target": pl.Float64,
        "low_mps": pl.Float64,
        "high_mps": pl.Float64,
        "speed_mps": pl.Float64,
        "in_range": pl.Boolean,
        "e": pl.Float64,
        "error": pl.Float64,
        "e_predicted": pl.Float64,
        "e_lowest": pl.Float64,
        "e_highest": pl.Float64,
        "penetration_m": pl.Float64,
        "penetration_bound_m": pl.Float64,
        "ok": pl.Boolean,
        "note": pl.String,
    }
)
"""One row per impact of a calibrated pair (columns: see `calibration_table`)."""
IMPACTS = {"run_id": pl.String, "side1": pl.String, "side2": pl.String, "impact": pl.Int64}


def impacts(bounces: pl.DataFrame, collisions: pl.DataFrame) -> pl.DataFrame:
    """The complete impacts of the analysis' tables: (run_id, side1, side2, impact, speed_mps,
    e, target_e, penetration_m), a bounce's sides its body and surface, a collision's its
    two bodies; the speed is the contact points' normal speed in (the closing speed)."""

    def pick(frame: pl.DataFrame, sides: tuple[str, str], n: str, speed: pl.Expr) -> pl.DataFrame:
        return frame.filter(pl.col("complete")).select(
            pl.col("run_id"),
            pl.col(sides[0]).alias("side1"),
            pl.col(sides[1]).alias("side2"),
            pl.col(n).cast(pl.Int64).alias("impact"),
            speed.alias("speed_mps"),
            pl.col("e_velocity").alias("e"),
            pl.col("target_e"),
            pl.col("max_penetration_m").alias("penetration_m"),
        )

    closing = pl.col("v1n_before_mps") - pl.col("v2n_before_mps")
    found = []
    if bounces.height:
        found.append(pick(bounces, ("body", "surface"), "bounce", -pl.col("v_in_mps")))
    if collisions.height:
        found.append(pick(collisions, ("body1", "body2"), "collision", closing))
    return pl.concat(found) if found else pl.DataFrame(schema=IMPACTS)


def calibration_table(
    runs: Sequence[PlannedRun], bounces: pl.DataFrame, collisions: pl.DataFrame
) -> pl.DataFrame:
    """Every impact of every calibrated pair of `runs`, measured by the analysis.

    An impact is in its pair's speed range when the analysis gives it the pair's target
    (`target_e`, an e(v)'s value at the impact's speed); there it must be within
    RESTITUTION_TOLERANCE of that target with the penetration within the designer's worst
    case. Outside the range the designer's step
    emulation predicts e at that speed (`e_predicted`, the band `e_lowest`..`e_highest` over
    where in a step the contact begins): it must lie in the band, widened by BAND_MARGIN. A
    pair without a complete impact is a row of its own, not ok, its note saying so.

    Returns:
        Columns of `SCHEMA`, by run, pair and impact.
    """
    found = impacts(bounces, collisions)
    rows: list[dict[str, Any]] = []
    for run in runs:
        mine = found.filter(pl.col("run_id") == run.info.run_id)
        for pair in run.pairs:
            p, names = pair.params, {pair.geom1, pair.geom2}
            hits = mine.filter(pl.col("side1").is_in(names) & pl.col("side2").is_in(names)).sort(
                "impact"
            )
            base = {
                "run_id": run.info.run_id,
                "pair": f"{pair.geom1}/{pair.geom2}",
                "target": p.restitution,
                "low_mps": p.speed_range_mps[0],
                "high_mps": p.speed_range_mps[1],
                "penetration_bound_m": p.max_penetration_m,
            }
            if hits.is_empty():
                rows.append({**base, "ok": False, "note": "no complete impact in the log"})
                continue
            mean, lowest, highest = restitution_spread(
                p,
                impact_speed_mps=hits["speed_mps"].to_numpy(),
                gravity_mps2=p.gravity_mps2,
                timestep_s=p.timestep_s,
            )
            for i, hit in enumerate(hits.iter_rows(named=True)):
                rows.append(_row(base, hit, float(mean[i]), float(lowest[i]), float(highest[i])))
    return pl.DataFrame(rows, schema=SCHEMA)


def _row(
    base: dict[str, Any], hit: dict[str, Any], mean: float, lowest: float, highest: float
) -> dict[str, Any]:
    """One impact's row: measured against the target (in range) or the prediction."""
    e, inside = hit["e"], hit["target_e"] is not None
    error = e - (hit["target_e"] if inside else base["target"])  # an e(v): at this speed
    if inside:
        ok = abs(error) <= RESTITUTION_TOLERANCE
        note = "" if ok else f"|e - target| = {abs(error):.4f} > {RESTITUTION_TOLERANCE}"
        bound = PENETRATION_MARGIN * base["penetration_bound_m"]
        if hit["penetration_m"] > bound:
            ok, note = False, f"penetration {hit['penetration_m']:.3g} m > {bound:.3g} m"
    else:
        ok = lowest - BAND_MARGIN <= e <= highest + BAND_MARGIN
        note = "" if ok else f"outside the predicted {lowest:.4f}..{highest:.4f}"
    return {
        **base,
        "impact": hit["impact"],
        "speed_mps": hit["speed_mps"],
        "in_range": inside,
        "e": e,
        "error": error,
        "e_predicted": mean,
        "e_lowest": lowest,
        "e_highest": highest,
        "penetration_m": hit["penetration_m"],
        "ok": ok,
        "note": note,
    }


def summary(table: pl.DataFrame) -> pl.DataFrame:
    """Per experiment and target: impacts in and outside the range, the largest |e - target|
    in it, the largest |e - predicted| outside it, and the impacts that are not ok."""
    experiment = pl.col("run_id").str.extract(r"^(.*?)-").fill_null(pl.col("run_id"))
    inside = pl.col("in_range").fill_null(False)
    return (
        table.with_columns(experiment.alias("experiment"))
        .group_by("experiment", "target", maintain_order=True)
        .agg(
            inside.sum().alias("in_range"),
            pl.col("error").filter(inside).abs().max().alias("max_error"),
            (~inside & pl.col("e").is_not_null()).sum().alias("outside"),
            (pl.col("e") - pl.col("e_predicted")).filter(~inside).abs().max().alias("max_off"),
            (~pl.col("ok")).sum().alias("failing"),
        )
        .sort("experiment", "target")
    )
