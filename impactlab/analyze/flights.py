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

from impactlab.analyze.ground import Ground
from impactlab.analyze.impacts import RK4

APEX_TURN_FRACTION = 1e-3
"""A flight whose lowest point moves relative to the centre of mass by more than this
fraction of the apex height turns too much for its apex to measure e (0.05 % of e)."""
APEX_TURN_FLOOR_M = 1e-9
"""Offset changes below this (rounding) never count as turning."""
FLIGHT_SCHEMA = {
    "run_id": pl.String,
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


def flights(rows: pl.DataFrame | None) -> pl.DataFrame:
    """One row per flight of each body of each run, with its apex above the surfaces around it.

    Args:
        rows: `flight_rows` of one or more runs (concatenated); None: no rows.

    Returns:
        (run_id, body, flight, n_rows, surface_before (left), surface_after (landed on
        next), apex_t_s, apex_after_m, apex_before_m (above those surfaces at the apex),
        reached (the apex lies within the logged flight), turning_after, turning_before).
    """
    if rows is None or rows.is_empty():
        return pl.DataFrame(schema=FLIGHT_SCHEMA)
    g = pl.col("g").first()
    apex = pl.col("z_up").arg_max()
    w_apex = pl.col("w").gather(apex)
    # the apex is inside the flight unless the flight starts descending (a release at rest)
    inside = (apex > 0) | (w_apex > 0)
    rise = pl.when(g > 0).then(pl.when(inside).then(w_apex**2 / (2 * g)).otherwise(0.0))

    def height(side: str) -> pl.Expr:
        return (pl.col(f"c_{side}").gather(apex) + rise).first()

    def turn(side: str) -> pl.Expr:
        offset = pl.col("z_up") - pl.col(f"c_{side}")
        return (offset.max() - offset.min()).alias(f"offset_range_{side}")

    per = rows.group_by("run_id", "body", "flight", maintain_order=True).agg(
        pl.len().alias("n_rows"),
        pl.col("surface_before").first(),
        pl.col("surface_after").first(),
        pl.col("t_s").gather(apex).first().alias("apex_t_s"),
        height("before").alias("apex_after_m"),  # above the surface left
        height("after").alias("apex_before_m"),  # above the surface landed on next
        ((pl.col("w").last() <= 0) & (g > 0)).alias("reached"),
        turn("before"),
        turn("after"),
    )
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


def flight_rows(
    run_id: str,
    states: pl.DataFrame,
    contacts: pl.DataFrame,
    ground: Ground,
    *,
    gravity: np.ndarray,
    integrator: str,
    timestep_s: float,
) -> pl.DataFrame | None:
    """The logged rows of each body of one run outside its ground contacts, by body and row:
    (run_id, body, flight, row, t_s, z_up (centre height along -gravity), w (velocity along
    -gravity minus g h, h as in `impactlab.analyze.impacts`), surface_before, surface_after,
    c_before, c_after (clearances to them), g (|gravity|)); None when there are none.

    Args:
        states: `states_long` of the run (sorted by body and row).
        contacts: the merged ground contacts of the run (body, other, first_row, last_row).
        ground: the run's ground (its clearances).

    A row belongs to the latest contact that begins at or before it (the body's contacts by
    first row) unless it lies after that contact's last row: then it is in flight `contact
    + 1` (0 before the first), between the surface of that contact and the next one's.
    """
    g = float(np.linalg.norm(gravity))
    up = -gravity / g if g > 0 else np.array([0.0, 0.0, 1.0])
    w_shift = g * (0.0 if integrator == RK4 else timestep_s / 2)
    ux, uy, uz = (float(u) for u in up)  # numpy scalars times an expression run as a ufunc
    z_up = ux * pl.col("x") + uy * pl.col("y") + uz * pl.col("z")
    v_up = ux * pl.col("vx") + uy * pl.col("vy") + uz * pl.col("vz")
    cols = states.select(
        "body", "row", "t_ns", "t_s", z_up.alias("z_up"), (v_up - w_shift).alias("w")
    )
    touch = contacts.sort("body", "first_row").select("body", "first_row", "last_row", "other")
    by_body = {str(b): f for (b,), f in touch.partition_by("body", as_dict=True).items()}
    parts = []
    for (body,), mine in cols.partition_by("body", as_dict=True, maintain_order=True).items():
        row = mine["row"].to_numpy()
        t_ns = mine["t_ns"].to_numpy()
        hit = by_body.get(str(body))
        first = hit["first_row"].to_numpy() if hit is not None else np.zeros(0, dtype=np.int64)
        last = hit["last_row"].to_numpy() if hit is not None else first
        surfaces = hit["other"].to_list() if hit is not None else []
        contact = np.searchsorted(first, row, side="right") - 1
        keep = np.ones(row.size, dtype=bool)
        if first.size:
            keep = (contact < 0) | (row > last[np.maximum(contact, 0)])
        flight = contact[keep] + 1
        t_kept = t_ns[keep]
        frame = {
            "run_id": pl.Series([run_id] * flight.size, dtype=pl.String),
            "body": pl.Series([str(body)] * flight.size, dtype=pl.String),
            "flight": flight,
        }
        frame |= {c: mine[c].to_numpy()[keep] for c in ("row", "t_s", "z_up", "w")}
        # flight j lies between contact j - 1 (the surface left) and contact j (landed on)
        for side, names in (("before", [None, *surfaces]), ("after", [*surfaces, None])):
            frame[f"surface_{side}"] = pl.Series(names, dtype=pl.String)[flight]
            c = np.full(flight.size, np.nan)
            found = np.zeros(flight.size, dtype=bool)
            for i, name in enumerate(names):
                spot = flight == i
                if name is not None and spot.any():
                    c[spot], found[spot] = ground.clearance_at(str(body), name, t_kept[spot])
            frame[f"c_{side}"] = pl.Series(c).scatter(np.flatnonzero(~found), None)
        frame["g"] = np.full(flight.size, g)
        parts.append(pl.DataFrame(frame))
    rows = pl.concat(parts) if parts else None
    return None if rows is None or rows.is_empty() else rows
