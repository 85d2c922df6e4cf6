"""Bounces of each body on the plane, from the contact channel (not from velocity thresholds).

Bounce n (1-based) is the n-th contact interval of a body with the plane. Heights are measured
from the contact height (centre minus radius above the plane, along -gravity); apex 0 is the
highest point before the first contact (the drop height above contact for a ball released at
rest). Normal velocities are along the contact normal pointing from the plane to the body:
v_in < 0 approaching, v_out > 0 leaving, taken at the last logged step before the contact and the
first after it; e_velocity = -v_out / v_in, e_apex = sqrt(apex(n) / apex(n-1)). The apex
predicted from the release is h_release + v_out^2 / (2 g), g the gravity along the normal.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from impactlab.analyze.contacts import state_at

BOUNCE_SCHEMA: dict[str, pl.DataType] = {
    "run_id": pl.String,
    "body": pl.String,
    "bounce": pl.Int64,
    "impact_t_s": pl.Float64,
    "release_t_s": pl.Float64,
    "duration_s": pl.Float64,
    "v_in_mps": pl.Float64,
    "v_out_mps": pl.Float64,
    "e_velocity": pl.Float64,
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


def plane_intervals(intervals: pl.DataFrame, bodies: list[str]) -> pl.DataFrame:
    """Intervals between a free body and the world (plane), with `body` and the normal's sign.

    `sign` is +1 when the body is body2 (the logged normal points from geom1 to geom2, i.e. from
    the plane to the body), -1 when it is body1.
    """
    return (
        intervals.filter(pl.col("body1").is_in(bodies) ^ pl.col("body2").is_in(bodies))
        .with_columns(
            pl.when(pl.col("body2").is_in(bodies))
            .then(pl.col("body2"))
            .otherwise(pl.col("body1"))
            .alias("body"),
            pl.when(pl.col("body2").is_in(bodies)).then(1.0).otherwise(-1.0).alias("sign"),
        )
        .sort("body", "start_t_ns")
        .with_columns((pl.int_range(pl.len()).over("body") + 1).alias("bounce"))
    )


def flight_apexes(heights: pl.DataFrame, contacts: pl.DataFrame, *, up: np.ndarray) -> pl.DataFrame:
    """Highest point of each flight of each body.

    Args:
        heights: per body and logged step: (body, t_ns, height_m, vx, vy, vz).
        contacts: the body's plane intervals (body, bounce, start_t_ns, end_t_ns).
        up: (3,) unit vector against gravity.

    Returns:
        (body, bounce, apex_m, apex_reached): the flight after bounce n (0: before the first
        contact); `apex_reached` is false when the log ends while the body is still rising.
    """
    vup = up[0] * pl.col("vx") + up[1] * pl.col("vy") + up[2] * pl.col("vz")
    return (
        heights.sort("t_ns")
        .join_asof(
            contacts.select("body", "bounce", "start_t_ns", "end_t_ns").sort("start_t_ns"),
            left_on="t_ns",
            right_on="start_t_ns",
            by="body",
            strategy="backward",
            check_sortedness=False,
        )
        .filter(pl.col("end_t_ns").is_null() | (pl.col("t_ns") > pl.col("end_t_ns")))
        .with_columns(pl.col("bounce").fill_null(0), vup.alias("v_up"))
        .group_by("body", "bounce")
        .agg(
            pl.col("height_m").max().alias("apex_m"),
            (pl.col("v_up").last() <= 0).alias("apex_reached"),
        )
        .sort("body", "bounce")
    )


def bounces(
    intervals: pl.DataFrame,
    states: pl.DataFrame,
    energy: pl.DataFrame,
    *,
    bodies: list[str],
    gravity: np.ndarray,
    step_ns: int,
) -> pl.DataFrame:
    """One row per bounce of each body on the plane (see the module docstring).

    Args:
        intervals: `contact_intervals` of the run.
        states: `states_long` of the run.
        energy: `run_energy` of the run (for height_m per body).
        bodies: names of the free bodies.
        gravity: (3,) m/s^2.
        step_ns: logged step, ns.

    Returns:
        Columns of `BOUNCE_SCHEMA`; an open interval is marked `complete` = false and not used
        for e; no rows when no body touches the plane.
    """
    g = float(np.linalg.norm(gravity))
    up = -gravity / g if g > 0 else np.array([0.0, 0.0, 1.0])
    hits = plane_intervals(intervals, bodies)
    if hits.is_empty():
        return pl.DataFrame(schema=BOUNCE_SCHEMA)
    heights = (
        energy.filter(pl.col("body") != "total")
        .select("body", "t_ns", "height_m")
        .join(states.select("body", "t_ns", "vx", "vy", "vz"), on=["body", "t_ns"])
    )
    apexes = flight_apexes(heights, hits, up=up)
    times = hits.with_columns(
        (pl.col("start_t_ns") - step_ns).alias("before_t_ns"),
        (pl.col("end_t_ns") + step_ns).alias("after_t_ns"),
    )
    times = state_at(states, times, on="before_t_ns", suffix="_in")
    times = state_at(states, times, on="after_t_ns", suffix="_out")
    h_out = heights.select(
        "body", pl.col("t_ns").alias("after_t_ns"), pl.col("height_m").alias("h_release_m")
    )
    times = times.join(h_out, on=["body", "after_t_ns"], how="left")

    def vn(s: str) -> pl.Expr:
        return pl.col("sign") * (
            pl.col("nx") * pl.col(f"vx{s}")
            + pl.col("ny") * pl.col(f"vy{s}")
            + pl.col("nz") * pl.col(f"vz{s}")
        )

    g_n = pl.col("sign") * -(
        gravity[0] * pl.col("nx") + gravity[1] * pl.col("ny") + gravity[2] * pl.col("nz")
    )
    after = apexes.select("body", "bounce", "apex_m", "apex_reached")
    before = apexes.select(
        "body",
        (pl.col("bounce") + 1).alias("bounce"),
        pl.col("apex_m").alias("apex_before_m"),
        pl.col("apex_reached").alias("before_reached"),
    )
    complete = ~pl.col("open") & pl.col("vx_in").is_not_null() & pl.col("vx_out").is_not_null()
    return (
        times.join(after, on=["body", "bounce"], how="left")
        .join(before, on=["body", "bounce"], how="left")
        .with_columns(vn("_in").alias("v_in_mps"), vn("_out").alias("v_out_mps"), g_n.alias("g_n"))
        .select(
            "run_id",
            "body",
            "bounce",
            (pl.col("start_t_ns") / 1e9).alias("impact_t_s"),
            pl.when(~pl.col("open")).then(pl.col("after_t_ns") / 1e9).alias("release_t_s"),
            "duration_s",
            "v_in_mps",
            pl.when(complete).then(pl.col("v_out_mps")).alias("v_out_mps"),
            pl.when(complete).then(-pl.col("v_out_mps") / pl.col("v_in_mps")).alias("e_velocity"),
            pl.when(pl.col("before_reached")).then(pl.col("apex_before_m")).alias("apex_before_m"),
            pl.when(complete & pl.col("apex_reached")).then(pl.col("apex_m")).alias("apex_m"),
            pl.when(complete & (pl.col("g_n") > 0))
            .then(pl.col("h_release_m") + pl.col("v_out_mps") ** 2 / (2 * pl.col("g_n")))
            .alias("apex_predicted_m"),
            pl.when(
                complete
                & pl.col("apex_reached")
                & pl.col("before_reached")
                & (pl.col("apex_before_m") > 0)
            )
            .then((pl.col("apex_m").clip(0.0) / pl.col("apex_before_m")).sqrt())
            .alias("e_apex"),
            "peak_force_N",
            "impulse_Ns",
            "max_penetration_m",
            complete.alias("complete"),
            pl.when(pl.col("open"))
            .then(pl.lit("contact still open at the end of the log (at rest or cut off)"))
            .when(pl.col("vx_in").is_null())
            .then(pl.lit("in contact at the first logged step"))
            .when(~pl.col("apex_reached").fill_null(False))
            .then(pl.lit("log ends before the apex after this bounce"))
            .otherwise(pl.lit(""))
            .alias("note"),
        )
        .cast(BOUNCE_SCHEMA)
        .sort("body", "bounce")
    )


def no_bounce_row(run_id: str, reason: str) -> pl.DataFrame:
    """The row a run without any bounce contributes: only the reason."""
    row = {k: None for k in BOUNCE_SCHEMA} | {"run_id": run_id, "complete": False, "note": reason}
    return pl.DataFrame([row], schema=BOUNCE_SCHEMA)
