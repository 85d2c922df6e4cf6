"""Bounces of each body on each ground surface: its impact episodes, with apex heights."""

from __future__ import annotations

import numpy as np
import polars as pl

from impactlab.analyze.measure.episodes import e_energy, e_velocity
from impactlab.physics import restitution_on_curve

BOUNCE_SCHEMA = pl.Schema(
    {
        "run_id": pl.String,
        "body": pl.String,
        "surface": pl.String,
        "bounce": pl.Int64,
        "impact_t_s": pl.Float64,
        "release_t_s": pl.Float64,
        "duration_s": pl.Float64,
        "v_in_mps": pl.Float64,
        "v_out_mps": pl.Float64,
        "e_velocity": pl.Float64,
        "e_energy": pl.Float64,
        "e_basis": pl.String,
        "target_e": pl.Float64,
        "apex_before_m": pl.Float64,
        "apex_m": pl.Float64,
        "apex_predicted_m": pl.Float64,
        "e_apex": pl.Float64,
        "peak_force_N": pl.Float64,
        "impulse_Ns": pl.Float64,
        "max_penetration_m": pl.Float64,
        "complete": pl.Boolean,
        "note": pl.String,
    }
)
TARGET_SCHEMA = pl.Schema(
    {
        "run_id": pl.String(),
        "body": pl.String(),
        "other": pl.String(),
        "target": pl.Float64(),
        "low_mps": pl.Float64(),
        "high_mps": pl.Float64(),
        "curve_speed_mps": pl.List(pl.Float64),
        "curve_e": pl.List(pl.Float64),
    }
)
"""A calibrated pair of a run: its target e over its speed range, a constant or, with the
curve's points, an e(v) (the log's contact_targets)."""


def target_e(speed: pl.Expr) -> pl.Expr:
    """The target e of an impact at a normal speed (m/s), over rows joined with its pair's
    `TARGET_SCHEMA` columns: inside the pair's speed range, the constant target or the
    curve's value (`physics.restitution_on_curve`; a range a step wider than the curve is
    held at its ends); none outside, and for a pair without a target."""
    points = pl.struct(speed.alias("v"), "curve_speed_mps", "curve_e")
    on_curve = points.map_batches(_on_curves, return_dtype=pl.Float64)
    return (
        pl.when(~speed.is_between(pl.col("low_mps"), pl.col("high_mps")))
        .then(None)
        .when(pl.col("curve_e").is_not_null())
        .then(on_curve)
        .otherwise(pl.col("target"))
    )


def _on_curves(rows: pl.Series) -> pl.Series:
    """Each row's curve (struct v, curve_speed_mps, curve_e) at its speed v, held at its ends
    (the rows of one curve at once)."""
    out = np.full(rows.len(), np.nan)
    v = rows.struct.field("v").cast(pl.Float64).fill_null(np.nan).to_numpy()
    curves: dict[tuple[tuple[float, ...], tuple[float, ...]], list[int]] = {}
    for i, (xs, es) in enumerate(zip(*(rows.struct.field(f) for f in CURVE), strict=True)):
        if xs is not None and es is not None and len(xs):
            curves.setdefault((tuple(xs), tuple(es)), []).append(i)
    for (xs, es), at in curves.items():
        out[at] = restitution_on_curve(np.clip(v[at], xs[0], xs[-1]), xs, es)
    return pl.Series(out, dtype=pl.Float64).fill_nan(None)


CURVE = ("curve_speed_mps", "curve_e")


TURNING = (
    "the body turns in flight (its lowest point moves relative to its centre of mass), so "
    "apex heights do not measure e"
)
ARTICULATED = (
    "an articulated body (moved by its joints between contacts, not ballistic): no apex "
    "heights; v_in, v_out and e are the contact point's, measured at every step"
)


def bounces(
    episodes: pl.DataFrame,
    flights: pl.DataFrame,
    *,
    gravity_n: pl.Expr,
    articulated: list[tuple[str, str]],
    targets: pl.DataFrame,
) -> pl.DataFrame:
    """One row per bounce: a body's impact episode on a surface (see docs/analysis.md).

    Args:
        episodes: the runs' ground episodes (`episodes.episodes`, kind "ground") with the
            per-body index `contact` (0-based, over every surface).
        flights: `impactlab.analyze.measure.flights.flights` of the runs.
        gravity_n: gravity along the release normal towards the surface (m/s^2), an
            expression over `episodes`.
        articulated: (run_id, body) of the bodies that are not ballistic.
        targets: the calibrated pairs (`TARGET_SCHEMA`): a bounce in its pair's speed range
            gets the pair's target e, any other none.

    Returns:
        Columns of `BOUNCE_SCHEMA`, sorted by run, body, surface and bounce.
    """
    rows = episodes.filter(pl.col("impact")).sort("run_id", "body", "other", "start_t_ns")
    if rows.is_empty():
        return pl.DataFrame(schema=BOUNCE_SCHEMA)

    def flight(shift: int, apex: str, reached: str, turning: str) -> pl.DataFrame:
        return flights.select(
            "run_id",
            "body",
            (pl.col("flight") + shift).alias("contact"),
            pl.col(apex),
            pl.col("reached").alias(reached),
            pl.col(turning),
        )

    links = pl.DataFrame(articulated, schema={"run_id": pl.String, "body": pl.String}, orient="row")
    rows = (
        rows.join(
            flight(0, "apex_before_m", "before_reached", "turning_before"),
            on=["run_id", "body", "contact"],
            how="left",
            maintain_order="left",
        )
        .join(
            flight(-1, "apex_after_m", "after_reached", "turning_after"),
            on=["run_id", "body", "contact"],
            how="left",
            maintain_order="left",
        )
        .join(
            links.with_columns(pl.lit(True).alias("articulated")),
            on=["run_id", "body"],
            how="left",
            maintain_order="left",
        )
        .join(targets, on=["run_id", "body", "other"], how="left", maintain_order="left")
        .with_columns(
            (pl.int_range(pl.len()).over("run_id", "body", "other") + 1).alias("bounce"),
            gravity_n.alias("g_n"),
            pl.col("articulated").fill_null(False),
        )
    )
    complete = ~pl.col("open")
    ballistic = ~pl.col("articulated")
    level = ~pl.col("turning_after").fill_null(True)
    apex_after = complete & pl.col("after_reached").fill_null(False) & level & ballistic
    apex_before = (
        pl.col("before_reached").fill_null(False)
        & ~pl.col("turning_before").fill_null(True)
        & ballistic
    )
    e_v = pl.when(complete).then(e_velocity())
    return (
        rows.with_columns(
            pl.when(apex_after).then(pl.col("apex_after_m")).alias("apex"),
            pl.when(apex_before).then(pl.col("apex_before_m")).alias("apex_b"),
        )
        .select(
            "run_id",
            "body",
            pl.col("other").alias("surface"),
            "bounce",
            "impact_t_s",
            pl.when(complete).then(pl.col("release_t_s")).alias("release_t_s"),
            pl.when(complete)
            .then(pl.col("release_t_s") - pl.col("impact_t_s"))
            .alias("duration_s"),
            "v_in_mps",
            pl.when(complete).then(pl.col("v_out_mps")).alias("v_out_mps"),
            e_v.alias("e_velocity"),
            e_energy().alias("e_energy"),
            pl.when(complete & ballistic & level & (e_v <= 1))
            .then(pl.lit("velocity"))
            .when(e_energy().is_not_null())
            .then(pl.lit("energy"))
            .alias("e_basis"),
            target_e(-pl.col("v_in_mps")).alias("target_e"),
            pl.col("apex_b").alias("apex_before_m"),
            pl.col("apex").alias("apex_m"),
            pl.when(complete & ballistic & level & (pl.col("g_n") > 0))
            .then(pl.col("v_out_mps") ** 2 / (2 * pl.col("g_n")))
            .alias("apex_predicted_m"),
            pl.when(pl.col("apex").is_not_null() & (pl.col("apex_b") > 0))
            .then((pl.col("apex").clip(0.0) / pl.col("apex_b")).sqrt())
            .alias("e_apex"),
            "peak_force_N",
            "impulse_Ns",
            "max_penetration_m",
            complete.alias("complete"),
            note().alias("note"),
        )
        .cast(BOUNCE_SCHEMA)
        .sort("run_id", "body", "surface", "bounce")
    )


def note() -> pl.Expr:
    """Why a bounce lacks a quantity (empty when it has them all)."""
    return (
        pl.when(pl.col("open"))
        .then(pl.format("still in contact with {} at the end of the run", pl.col("other")))
        .when(pl.col("e_note") != "")
        .then(pl.col("e_note"))
        .when(pl.col("articulated"))
        .then(pl.lit(ARTICULATED))
        .when(pl.col("turning_after").fill_null(False))
        .then(pl.lit(TURNING))
        .when(pl.col("apex_after_m").is_null())
        .then(pl.lit("no clearance to this surface in the log, so no heights"))
        .when(~pl.col("after_reached").fill_null(False))
        .then(pl.lit("the log ends before the apex after this bounce"))
        .otherwise(pl.lit(""))
    )
