"""Contact intervals of each body with each ground surface and with each other body.

A body touches a surface (or another body) at a logged row when the log holds a message on
one of their geom pairs' contact topics at that row; the body's geoms are taken together.
Consecutive rows in contact form a raw interval. Each row's contact point is the mean of its
points and its normal the first point's, oriented from the surface to the body (for two
bodies, from `body` to `other`, as logged). Rows are numbered over the run's logged steps
(`row`), so a log written every N steps, or with its last (stop) step off that grid, is read
the same way. A raw interval reaching the last row is `open`.

Raw intervals separated by no visible flight are merged into one contact
(`impactlab.analyze.impacts.merge_chatter`).
"""

from __future__ import annotations

import numpy as np
import polars as pl

from impactlab.analyze.ground import Ground
from impactlab.logs.load import RunLog
from impactlab.logs.messages import BODY_FIELDS

PAIR = ("kind", "body", "other")
"""An interval's pair: kind "ground" (body on the surface `other`) or "body" (two bodies)."""


def states_long(run: RunLog) -> pl.DataFrame:
    """Every body's state in one frame: (run_id, body, row, t_ns, t_s, x .. wz), by body, time.

    `row` numbers the run's logged steps from 0.
    """
    frames = [
        frame.with_columns(pl.lit(name).alias("body")).select(
            "run_id", "body", pl.exclude("run_id", "body")
        )
        for name, frame in run.bodies.items()
    ]
    if not frames:
        schema = {"run_id": pl.String, "body": pl.String, "row": pl.Int64, "t_ns": pl.Int64}
        schema |= {"t_s": pl.Float64} | {c: pl.Float64 for c in BODY_FIELDS}
        return pl.DataFrame(schema=schema)
    return (
        pl.concat(frames)
        .with_columns((pl.col("t_ns").rank("dense") - 1).cast(pl.Int64).alias("row"))
        .select("run_id", "body", "row", pl.exclude("run_id", "body", "row"))
        .sort("body", "t_ns")
    )


def row_numbers(states: pl.DataFrame) -> pl.DataFrame:
    """(t_ns, row) of the run's logged rows, from `states_long` (whose `row` numbers the
    distinct logged times in order)."""
    t_ns = np.unique(states["t_ns"].to_numpy())
    return pl.DataFrame(
        {"t_ns": pl.Series(t_ns, dtype=pl.Int64), "row": np.arange(t_ns.size, dtype=np.int64)}
    )


def contact_rows(run: RunLog, ground: Ground, rows: pl.DataFrame) -> pl.DataFrame:
    """One row per pair (kind, body, other) and logged row in contact.

    Returns:
        (run_id, kind, body, other, row, t_ns, n_points, normal_force_N (sum over the
        points), penetration_m (max), pen (mean), px, py, pz (mean point), nx, ny, nz
        (oriented, see the module docstring)).
    """
    bodies = list(run.bodies)
    surfaces = list(ground.surfaces)
    c = run.contacts
    on_ground_2 = pl.col("geom1").is_in(surfaces) & pl.col("body2").is_in(bodies)
    on_ground_1 = pl.col("geom2").is_in(surfaces) & pl.col("body1").is_in(bodies)
    two_bodies = pl.col("body1").is_in(bodies) & pl.col("body2").is_in(bodies)
    tagged = c.with_columns(
        pl.when(on_ground_2 | on_ground_1)
        .then(pl.lit("ground"))
        .when(two_bodies)
        .then(pl.lit("body"))
        .alias("kind"),
        (on_ground_1 & ~on_ground_2).alias("flip"),  # the surface is geom2
    ).filter(pl.col("kind").is_not_null())
    ground_pair = pl.col("kind") == "ground"
    sign = pl.when(pl.col("flip")).then(-1.0).otherwise(1.0)
    tagged = tagged.with_columns(
        pl.when(ground_pair & ~pl.col("flip"))
        .then(pl.col("body2"))
        .otherwise(pl.col("body1"))
        .alias("body"),
        pl.when(~ground_pair)
        .then(pl.col("body2"))
        .when(pl.col("flip"))
        .then(pl.col("geom2"))
        .otherwise(pl.col("geom1"))
        .alias("other"),
        *[(sign * pl.col(f"n{a}")).alias(f"n{a}") for a in "xyz"],
    )
    steps = tagged.group_by("run_id", *PAIR, "t_ns").agg(
        pl.len().alias("n_points"),
        pl.col("normal_force").sum().alias("normal_force_N"),
        pl.col("penetration").max().alias("penetration_m"),
        pl.col("penetration").mean().alias("pen"),
        pl.col("x").mean().alias("px"),
        pl.col("y").mean().alias("py"),
        pl.col("z").mean().alias("pz"),
        pl.col("nx").first(),
        pl.col("ny").first(),
        pl.col("nz").first(),
    )
    # each step's row number (an inner join on t_ns with `rows`, sorted by time)
    t_ns, logged = steps["t_ns"].to_numpy(), rows["t_ns"].to_numpy()
    spot = np.clip(np.searchsorted(logged, t_ns), 0, max(logged.size - 1, 0))
    found = logged[spot] == t_ns if logged.size else np.zeros(t_ns.size, dtype=bool)
    row = pl.Series("row", rows["row"].to_numpy()[spot] if logged.size else spot, dtype=pl.Int64)
    return steps.with_columns(row).filter(pl.Series(found)).sort(*PAIR, "row")


def raw_intervals(steps: pl.DataFrame, *, last_row: int, interval_s: float) -> pl.DataFrame:
    """Group consecutive contact rows of each pair into raw intervals.

    Args:
        steps: `contact_rows` output.
        last_row: the run's last logged row.
        interval_s: the nominal time between logged rows (for the impulse), s.

    Returns:
        One row per interval: the pair, `interval` (0-based per pair), first_row, last_row,
        start_t_ns, end_t_ns, n_steps, peak_force_N, impulse_Ns (sum of normal force x
        interval_s), max_penetration_m, the point, normal and mean penetration at the first
        row (px_in .. nz_in, pen_in) and at the last row (px_out .. pen_out), and `open`
        (reaches the last row).
    """
    pair = list(PAIR)
    point = ("px", "py", "pz", "nx", "ny", "nz", "pen")
    return (
        steps.sort(*pair, "row")
        .with_columns(
            pl.col("row").diff().fill_null(1).ne(1).cum_sum().over(pair).alias("interval")
        )
        .group_by("run_id", *pair, "interval", maintain_order=True)
        .agg(
            pl.col("row").first().alias("first_row"),
            pl.col("row").last().alias("last_row"),
            pl.col("t_ns").first().alias("start_t_ns"),
            pl.col("t_ns").last().alias("end_t_ns"),
            pl.len().alias("n_steps"),
            pl.col("normal_force_N").max().alias("peak_force_N"),
            (pl.col("normal_force_N").sum() * interval_s).alias("impulse_Ns"),
            pl.col("penetration_m").max().alias("max_penetration_m"),
            *[pl.col(c).first().alias(f"{c}_in") for c in point],
            *[pl.col(c).last().alias(f"{c}_out") for c in point],
        )
        .with_columns(
            (pl.col("last_row") >= last_row).alias("open"),
            pl.col("interval").cast(pl.Int64),
        )
        .sort("start_t_ns", *pair)
    )


def state_at(states: pl.DataFrame, frame: pl.DataFrame, *, body: str, row: str, suffix: str):
    """Join each row of `frame` with the state of the body named in column `body` at the row
    number in column `row`; the state's columns get `suffix` (nulls where there is none)."""
    cols = ["t_ns", "x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz"]
    right = states.select(
        pl.col("body").alias(body),
        pl.col("row").alias(row),
        *[pl.col(c).alias(c + suffix) for c in cols],
    )
    return frame.join(right, on=[body, row], how="left")
