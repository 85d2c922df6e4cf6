"""Contact intervals from the contact channel, and the body states around them.

A pair of geoms is in contact at a logged step when the log holds a message on the pair's topic
at that step. A contact interval is a run of consecutive logged steps (step index = t_ns /
logged step) with a message; the state "before" is the body state at the last logged step before
the interval, "after" the state at the first logged step after it. An interval that reaches the
last logged step is open (incomplete): its "after" state does not exist.
"""

from __future__ import annotations

import polars as pl

from impactlab.logs.load import RunLog

PAIR = ("geom1", "geom2", "body1", "body2")


def logged_step_ns(run: RunLog) -> int:
    """Time between two logged rows in integer ns (timestep x log_every, as the recorder does)."""
    step_ns = max(1, round(run.timestep_s * 1e9))
    return step_ns * int(run.meta.get("log_every", "1") or 1)


def states_long(run: RunLog) -> pl.DataFrame:
    """Every body's state in one frame: (run_id, body, t_ns, t_s, x .. wz), sorted by body, time."""
    frames = [
        frame.with_columns(pl.lit(name).alias("body")).select(
            "run_id", "body", pl.exclude("run_id", "body")
        )
        for name, frame in run.bodies.items()
    ]
    if not frames:
        return pl.DataFrame(schema={"run_id": pl.String, "body": pl.String, "t_ns": pl.Int64})
    return pl.concat(frames).sort("body", "t_ns")


def contact_steps(contacts: pl.DataFrame, *, step_ns: int) -> pl.DataFrame:
    """One row per pair and logged step in contact, the points summed.

    Returns:
        (run_id, geom1, geom2, body1, body2, t_ns, step, n_points, normal_force_N (sum over the
        points), penetration_m (max), nx, ny, nz (first point, geom1 -> geom2)).
    """
    return (
        contacts.group_by("run_id", *PAIR, "t_ns", maintain_order=True)
        .agg(
            pl.len().alias("n_points"),
            pl.col("normal_force").sum().alias("normal_force_N"),
            pl.col("penetration").max().alias("penetration_m"),
            pl.col("nx").first(),
            pl.col("ny").first(),
            pl.col("nz").first(),
        )
        .with_columns((pl.col("t_ns") // step_ns).alias("step"))
        .sort(*PAIR, "t_ns")
    )


def contact_intervals(steps: pl.DataFrame, *, step_ns: int, last_t_ns: int) -> pl.DataFrame:
    """Group consecutive contact steps of each pair into intervals.

    Args:
        steps: `contact_steps` output.
        step_ns: logged step in ns.
        last_t_ns: time of the run's last logged row, ns.

    Returns:
        One row per interval: the pair, `interval` (0-based per pair), start_t_ns and end_t_ns
        (first and last logged step in contact), n_steps, duration_s (n_steps x logged step),
        peak_force_N, impulse_Ns (sum of normal force x logged step), max_penetration_m, the
        normal at the first step (nx, ny, nz) and `open` (reaches the end of the log).
    """
    dt_s = step_ns / 1e9
    pair = list(PAIR)
    return (
        steps.sort(*pair, "t_ns")
        .with_columns(
            (pl.col("step").diff().fill_null(1).ne(1).cum_sum().over(pair)).alias("interval")
        )
        .group_by("run_id", *pair, "interval", maintain_order=True)
        .agg(
            pl.col("t_ns").first().alias("start_t_ns"),
            pl.col("t_ns").last().alias("end_t_ns"),
            pl.len().alias("n_steps"),
            pl.col("normal_force_N").max().alias("peak_force_N"),
            (pl.col("normal_force_N").sum() * dt_s).alias("impulse_Ns"),
            pl.col("penetration_m").max().alias("max_penetration_m"),
            pl.col("nx").first(),
            pl.col("ny").first(),
            pl.col("nz").first(),
        )
        .with_columns(
            (pl.col("n_steps") * dt_s).alias("duration_s"),
            (pl.col("end_t_ns") >= last_t_ns).alias("open"),
            pl.col("interval").cast(pl.Int64),
        )
        .sort("start_t_ns", *pair)
    )


def run_intervals(run: RunLog) -> pl.DataFrame:
    """The contact intervals of one run (empty frame with the same columns when none)."""
    step_ns = logged_step_ns(run)
    last = max((int(f["t_ns"].max()) for f in run.bodies.values() if f.height), default=0)
    return contact_intervals(
        contact_steps(run.contacts, step_ns=step_ns), step_ns=step_ns, last_t_ns=last
    )


def state_at(states: pl.DataFrame, times: pl.DataFrame, *, on: str, suffix: str) -> pl.DataFrame:
    """Join each row of `times` with the body state at time `on` (exact ns), columns suffixed.

    `times` must have columns `body` and `on`; missing states give nulls.
    """
    cols = ["x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz"]
    right = states.select(
        "body", pl.col("t_ns").alias(on), *[pl.col(c).alias(f"{c}{suffix}") for c in cols]
    )
    return times.join(right, on=["body", on], how="left")
