"""Free flights of each body between its ground contacts, and their apexes.

Flight j of a body is the run of logged rows after its j-th contact with any ground surface
(flight 0: before the first) and before the next. Its apex is the logged row where the
centre of mass is highest along -gravity, refined ballistically: the height above a surface
at the true apex is c + w^2 / (2 g), c the clearance at that row and w = v_up - g h its
velocity along -gravity (h as in `impactlab.analyze.impacts`), unless the flight begins
descending (a release at rest: the apex is its first row). It is measured above the
surface the body left (`apex_after_m`) and the one it lands on next (`apex_before_m`).

A height above a surface is the apex of the body only when the body does not turn in
flight: the lowest point must keep its place below the centre of mass. `turning_*` says the
offset (centre height minus clearance) changed by more than APEX_TURN_FRACTION of the apex
height over the flight; such apexes are left empty by the bounce table, with the reason.
"""

from __future__ import annotations

import numpy as np
import polars as pl

from impactlab.analyze.impacts import RK4

APEX_TURN_FRACTION = 1e-3
"""A flight whose lowest point moves relative to the centre of mass by more than this
fraction of the apex height turns too much for its apex to measure e (0.05 % of e)."""
APEX_TURN_FLOOR_M = 1e-9
"""Offset changes below this (rounding) never count as turning."""
FLIGHT_SCHEMA = {
    "body": pl.String,
    "flight": pl.Int64,
    "n_rows": pl.UInt32,
    "surface_before": pl.String,
    "surface_after": pl.String,
    "apex_t_s": pl.Float64,
    "apex_after_m": pl.Float64,
    "apex_before_m": pl.Float64,
    "reached": pl.Boolean,
    "turning_after": pl.Boolean,
    "turning_before": pl.Boolean,
}


def flights(
    states: pl.DataFrame,
    contacts: pl.DataFrame,
    clearance: pl.DataFrame,
    *,
    gravity: np.ndarray,
    integrator: str,
    timestep_s: float,
) -> pl.DataFrame:
    """One row per flight of each body, with its apex above the surfaces around it.

    Args:
        states: `states_long` of the run.
        contacts: the merged ground contacts of the run (body, other, first_row, last_row).
        clearance: the ground's clearance frame (body, surface, t_ns, clearance_m).

    Returns:
        (body, flight, n_rows, surface_before (left), surface_after (landed on next),
        apex_t_s, apex_after_m, apex_before_m (above those surfaces at the apex), reached
        (the apex lies within the logged flight), turning_after, turning_before).
    """
    g = float(np.linalg.norm(gravity))
    up = -gravity / g if g > 0 else np.array([0.0, 0.0, 1.0])
    h = 0.0 if integrator == RK4 else timestep_s / 2
    touch = (
        contacts.sort("body", "first_row")
        .with_columns(pl.int_range(pl.len()).over("body").alias("contact"))
        .select("body", "contact", "first_row", "last_row", pl.col("other").alias("surface"))
    )
    z_up = up[0] * pl.col("x") + up[1] * pl.col("y") + up[2] * pl.col("z")
    v_up = up[0] * pl.col("vx") + up[1] * pl.col("vy") + up[2] * pl.col("vz")
    rows = (
        states.select("body", "row", "t_ns", "t_s", z_up.alias("z_up"), (v_up - g * h).alias("w"))
        .sort("row")
        .join_asof(
            touch.sort("first_row"),
            left_on="row",
            right_on="first_row",
            by="body",
            strategy="backward",
            check_sortedness=False,
        )
        .filter(pl.col("last_row").is_null() | (pl.col("row") > pl.col("last_row")))
        .with_columns((pl.col("contact").fill_null(-1) + 1).cast(pl.Int64).alias("flight"))
        .drop("first_row", "last_row", "contact")
        .rename({"surface": "surface_before"})
    )
    if rows.is_empty():
        return pl.DataFrame(schema=FLIGHT_SCHEMA)
    nxt = touch.select(
        "body", pl.col("contact").alias("flight"), pl.col("surface").alias("surface_after")
    )
    rows = rows.join(nxt, on=["body", "flight"], how="left")
    for side in ("before", "after"):
        right = clearance.select(
            "body",
            pl.col("surface").alias(f"surface_{side}"),
            "t_ns",
            pl.col("clearance_m").alias(f"c_{side}"),
        )
        rows = rows.join(right, on=["body", f"surface_{side}", "t_ns"], how="left")
    apex = pl.col("z_up").arg_max()
    w_apex = pl.col("w").gather(apex)
    # the apex is inside the flight unless the flight starts descending (a release at rest)
    inside = (apex > 0) | (w_apex > 0)
    rise = (
        pl.when(inside).then(w_apex**2 / (2 * g)).otherwise(0.0)
        if g > 0
        else pl.lit(None, dtype=pl.Float64)
    )

    def height(side: str) -> pl.Expr:
        return (pl.col(f"c_{side}").gather(apex) + rise).first()

    def turn(side: str) -> pl.Expr:
        offset = pl.col("z_up") - pl.col(f"c_{side}")
        return (offset.max() - offset.min()).alias(f"offset_range_{side}")

    per = (
        rows.sort("body", "row")
        .group_by("body", "flight", maintain_order=True)
        .agg(
            pl.len().alias("n_rows"),
            pl.col("surface_before").first(),
            pl.col("surface_after").first(),
            pl.col("t_s").gather(apex).first().alias("apex_t_s"),
            height("before").alias("apex_after_m"),  # above the surface left
            height("after").alias("apex_before_m"),  # above the surface landed on next
            (pl.col("w").last() <= 0).alias("reached"),
            turn("before"),
            turn("after"),
        )
    )
    if g <= 0:
        per = per.with_columns(pl.lit(False).alias("reached"))
    return (
        per.with_columns(
            (
                pl.col("offset_range_before")
                > APEX_TURN_FRACTION * pl.col("apex_after_m").abs() + APEX_TURN_FLOOR_M
            ).alias("turning_after"),
            (
                pl.col("offset_range_after")
                > APEX_TURN_FRACTION * pl.col("apex_before_m").abs() + APEX_TURN_FLOOR_M
            ).alias("turning_before"),
        )
        .select(list(FLIGHT_SCHEMA))
        .cast(FLIGHT_SCHEMA)
    )
