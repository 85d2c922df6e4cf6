"""Contact intervals of each body with each ground surface and with each other body.

A body touches a surface (or another body) at a logged row when the log holds a message on
one of their geom pairs' contact topics at that row; the body's geoms are taken together.
Consecutive rows in contact form a raw interval. Each row's contact point is the mean of its
points and its normal the first point's, oriented from the surface to the body (for two
bodies, from `body` to `other`, as logged). Rows are numbered over the run's logged steps
(`row`), so a log written every N steps, or with its last (stop) step off that grid, is read
the same way. A raw interval reaching the last row is `open`.

Raw intervals separated by no visible flight are merged into one contact
(`impactlab.analyze.measure.impacts.merge_chatter`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import polars as pl

from impactlab.analyze.measure.states import logged_interval_s, per_run
from impactlab.logs.load import RunLog

PAIR = ("kind", "body", "other")
"""An interval's pair: kind "ground" (body on the surface `other`) or "body" (two bodies)."""


def contact_rows(
    runs: Sequence[RunLog], surfaces: Sequence[str], rows: pl.DataFrame
) -> pl.DataFrame:
    """One row per run, pair (kind, body, other) and logged row in contact.

    Args:
        runs: runs whose bodies and ground `surfaces` are the same (their names).
        rows: the runs' logged rows (`states_long`).

    Returns:
        (run_id, kind, body, other, row, t_ns, n_points, normal_force_N (sum over the
        points), penetration_m (max), pen (mean), px, py, pz (mean point), nx, ny, nz
        (oriented, see the module docstring)), by run, pair and row.
    """
    bodies = list(runs[0].bodies) if runs else []
    surfaces = list(surfaces)
    c = pl.concat([run.contacts for run in runs]) if len(runs) > 1 else runs[0].contacts
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
    keys = ["run_id", *PAIR, "t_ns"]
    if not _grouped_by_time(tagged):  # as decoded it mostly is: each pair's channel by time
        tagged = tagged.sort(keys, maintain_order=True)
    if _one_point_per_step(tagged):  # the group-by below would keep every row as it is
        steps = tagged.select(
            *keys,
            pl.lit(1, dtype=pl.UInt32).alias("n_points"),
            pl.col("normal_force").alias("normal_force_N"),
            pl.col("penetration").alias("penetration_m"),
            pl.col("penetration").alias("pen"),
            pl.col("x").alias("px"),
            pl.col("y").alias("py"),
            pl.col("z").alias("pz"),
            "nx",
            "ny",
            "nz",
        )
    else:
        steps = tagged.group_by(keys, maintain_order=True).agg(
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
    return with_rows(steps, rows)


def with_rows(steps: pl.DataFrame, rows: pl.DataFrame) -> pl.DataFrame:
    """`steps` (each run's rows together) with the row number of each step's t_ns, those at
    a time the run did not log left out: an inner join on (run_id, t_ns) with `rows`."""
    if not steps.height:
        return steps.with_columns(pl.lit(None, dtype=pl.Int64).alias("row")).clear()
    logged = dict(_run_blocks(rows, rows["t_ns"].to_numpy()))
    runs = steps["run_id"].rle()
    t_ns = steps["t_ns"].to_numpy()
    row = np.full(t_ns.size, -1, dtype=np.int64)
    start = 0
    for run, length in zip(runs.struct.field("value"), runs.struct.field("len"), strict=True):
        times, stop = logged.get(run), start + length
        if times is not None and times.size:
            mine = t_ns[start:stop]
            spot = np.clip(np.searchsorted(times, mine), 0, times.size - 1)
            row[start:stop] = np.where(times[spot] == mine, spot, -1)
        start = stop
    found = row >= 0
    out = steps.hstack([pl.Series("row", row, dtype=pl.Int64)])
    return out if found.all() else out.filter(pl.Series(found))


def _run_blocks(rows: pl.DataFrame, values: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """(run_id, its rows' part of `values`) for each run of `rows`, in order: slices when each
    run's rows are together (`states_long`), else gathered by a partition."""
    blocks = rows["run_id"].rle()
    ids = blocks.struct.field("value").to_list()
    if len(set(ids)) != len(ids):
        parts = rows.with_row_index("_i").partition_by("run_id", as_dict=True)
        return [(str(k[0]), values[f["_i"].to_numpy()]) for k, f in parts.items()]
    lengths = blocks.struct.field("len").to_numpy()
    ends = np.cumsum(lengths)
    return [(r, values[e - n : e]) for r, n, e in zip(ids, lengths, ends, strict=True)]


def _grouped_by_time(tagged: pl.DataFrame) -> bool:
    """Whether each (run, pair) of `tagged` is one block of rows, by time (what a sort by
    run, pair and time would give but for the order of the blocks)."""
    if tagged.height < 2:
        return True
    changed = [pl.col(c) != pl.col(c).shift() for c in ("run_id", *PAIR)]
    new = tagged.select(pl.any_horizontal(changed).fill_null(True)).to_series().to_numpy()
    t = tagged["t_ns"].to_numpy()
    if not (new[1:] | (t[1:] >= t[:-1])).all():
        return False
    starts = np.flatnonzero(new)
    heads = tagged[starts].select("run_id", *PAIR).rows()
    return len(set(heads)) == len(heads)


def _one_point_per_step(tagged: pl.DataFrame) -> bool:
    """Whether each (run, pair, t_ns) of `tagged` (sorted by them) has one contact point whose
    values are all set (then each step's sums and means are that point's values)."""
    if not tagged.height:
        return True
    values = ("normal_force", "penetration", "x", "y", "z", "nx", "ny", "nz")
    if any(tagged[c].null_count() for c in values):
        return False
    same = [pl.col(c) == pl.col(c).shift() for c in ("run_id", *PAIR, "t_ns")]
    return not tagged.select(pl.all_horizontal(same).any()).item()


def raw_intervals(steps: pl.DataFrame, runs: Sequence[RunLog], rows: pl.DataFrame) -> pl.DataFrame:
    """Group consecutive contact rows of each run's pairs into raw intervals.

    Args:
        steps: `contact_rows` of the runs (each run's rows together, by pair and row).
        runs: the runs (the nominal time between their logged rows gives the impulse).
        rows: the runs' logged rows (`states_long`: each run's together, from row 0).

    Returns:
        One row per interval: the pair, `interval` (0-based per pair), first_row, last_row,
        start_t_ns, end_t_ns, n_steps, peak_force_N, impulse_Ns (sum of normal force x
        interval_s), max_penetration_m, the point, normal and mean penetration at the first
        row (px_in .. nz_in, pen_in) and at the last row (px_out .. pen_out), and `open`
        (reaches the run's last row); by run, then time.
    """
    pair = ["run_id", *PAIR]
    point = ("px", "py", "pz", "nx", "ny", "nz", "pen")
    blocks = rows["run_id"].rle()  # each run's rows are together, numbered from 0
    last = dict(
        zip(
            blocks.struct.field("value").to_list(),
            blocks.struct.field("len").to_list(),
            strict=True,
        )
    )
    interval_s = per_run(runs, logged_interval_s)
    last_row = pl.col("run_id").replace_strict(
        {r: n - 1 for r, n in last.items()}, default=0, return_dtype=pl.Int64
    )
    # each (run, pair) is one block of rows by row number (`contact_rows`): an interval
    # starts where the pair changes or a row is skipped, found in numpy and grouped by its
    # number (an integer key: not the four string columns)
    pid = steps.select(pl.struct(pair).rle_id()).to_series().to_numpy()
    row = steps["row"].to_numpy()
    new_pair = np.ones(steps.height, dtype=bool)
    new_pair[1:] = pid[1:] != pid[:-1]
    start = new_pair.copy()
    start[1:] |= row[1:] - row[:-1] != 1
    number = np.cumsum(start) - 1
    interval = number - np.maximum.accumulate(np.where(new_pair, number, 0))
    starts = np.flatnonzero(start)
    found = (
        steps.with_columns(pl.Series("_interval", number))
        .group_by("_interval", maintain_order=True)
        .agg(
            pl.col("row").first().alias("first_row"),
            pl.col("row").last().alias("last_row"),
            pl.col("t_ns").first().alias("start_t_ns"),
            pl.col("t_ns").last().alias("end_t_ns"),
            pl.len().alias("n_steps"),
            pl.col("normal_force_N").max().alias("peak_force_N"),
            (pl.col("normal_force_N").sum() * interval_s.first()).alias("impulse_Ns"),
            pl.col("penetration_m").max().alias("max_penetration_m"),
            *[pl.col(c).first().alias(f"{c}_in") for c in point],
            *[pl.col(c).last().alias(f"{c}_out") for c in point],
        )
        .drop("_interval")
    )
    keys = steps[starts].select(pair)
    keys = keys.with_columns(pl.Series("interval", interval[starts], dtype=pl.Int64))
    return (
        pl.concat([keys, found], how="horizontal")
        .with_columns((pl.col("last_row") >= last_row).alias("open"))
        .sort("run_id", "start_t_ns", *PAIR)
    )
