"""Analysis of one run: every quantity frame, and the run's one-row summary."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import polars as pl

from impactlab.analyze.bounces import bounces, no_bounce_rows
from impactlab.analyze.collisions import collisions, no_collision_rows
from impactlab.analyze.contacts import contact_rows, raw_intervals, row_numbers, states_long
from impactlab.analyze.energy import energy_phases, references, run_energy
from impactlab.analyze.flights import flights
from impactlab.analyze.ground import Ground, run_ground
from impactlab.analyze.impacts import approach_and_release, merge_chatter
from impactlab.analyze.summary import summary_row
from impactlab.errors import LogError
from impactlab.logs.load import RunLog


@dataclass
class RunAnalysis:
    """Everything computed for one run.

    Attributes:
        run: the decoded log.
        states: every body's state (`states_long`).
        intervals: contacts of every pair, chatter merged (`impacts.merge_chatter`).
        energy: energy per body and total ("total" rows), full resolution.
        phases: flight and contact phases with energy drift and loss.
        bounces: one row per bounce of a body on a surface (rows with the reason for bodies
            without any).
        collisions: one row per body-body contact (rows with the reason when a collision was
            expected and none happened).
        summary: the run's row of the runs table.
        ground: the run's ground surfaces and clearances.
        energy_logged: rows of `energy` at full resolution and the most of one body, kept
            when `energy` is decimated (`impactlab.analyze.batch.slim`).
    """

    run: RunLog
    states: pl.DataFrame
    intervals: pl.DataFrame
    energy: pl.DataFrame
    phases: pl.DataFrame
    bounces: pl.DataFrame
    collisions: pl.DataFrame
    summary: dict[str, Any]
    ground: Ground | None = None
    energy_logged: tuple[int, int] = (0, 0)


def logged_interval_s(run: RunLog) -> float:
    """Time between two logged rows, s (timestep x log_every, as the recorder logs)."""
    return run.timestep_s * run.log_every


def expects_collision(run: RunLog) -> bool:
    """Whether the run was meant to bring two bodies together (a `stop.separation` rule)."""
    stop = run.spec.get("stop")
    return isinstance(stop, dict) and stop.get("separation") is not None


def analyze_run(run: RunLog) -> RunAnalysis:
    """Compute energy, bounces, collisions and the summary row of one decoded log.

    Raises:
        LogError: the metadata the analysis needs (masses, sizes, gravity, ground, timestep,
            logging stride, integrator) is missing, damaged or contradicts the channels; the
            message names the key.
    """
    reason = run.unanalyzable()
    if reason is not None:
        raise LogError(str(run.path), reason)
    ground = run_ground(run)
    states = states_long(run)
    rows = row_numbers(states)
    interval_s = logged_interval_s(run)
    raw = raw_intervals(
        contact_rows(run, ground, rows),
        last_row=int(rows["row"].max() or 0) if rows.height else 0,
        interval_s=interval_s,
    )
    raw = approach_and_release(
        raw,
        states,
        ground,
        spheres=[n for n, info in run.body_info.items() if info.radius is not None],
        gravity=run.gravity,
        integrator=run.integrator,
        timestep_s=run.timestep_s,
        interval_s=interval_s,
    )
    contacts = merge_chatter(raw).with_columns(pl.lit(interval_s).alias("interval_s"))
    on_ground = (
        contacts.filter(pl.col("kind") == "ground")
        .sort("body", "first_row")
        .with_columns(pl.int_range(pl.len()).over("body").alias("contact"))
    )
    first: dict[str, str] = {}  # each body's first ground contact: the surface
    for body, other in zip(on_ground["body"].to_list(), on_ground["other"].to_list(), strict=True):
        first.setdefault(body, other)
    refs = references(run, ground, states, first)
    energy = run_energy(run, states, ground, refs)
    total = energy.filter(pl.col("body") == "total").sort("t_ns")
    phases = energy_phases(total, contact_times(contacts, rows))
    fl = flights(
        states,
        on_ground,
        ground,
        gravity=run.gravity,
        integrator=run.integrator,
        timestep_s=run.timestep_s,
    )
    g = [float(x) for x in run.gravity]
    g_n = -(g[0] * pl.col("nx_out") + g[1] * pl.col("ny_out") + g[2] * pl.col("nz_out"))
    bnc = bounces(on_ground, fl, gravity_n=g_n)
    names = [n for n in run.body_info if n in run.bodies]
    if ground.surfaces:
        missing = [n for n in names if n not in set(bnc["body"].to_list())]
        reasons = {n: no_bounce_reason(n, on_ground, states) for n in missing}
        if reasons:
            bnc = pl.concat([bnc, no_bounce_rows(run.run_id, reasons)])
    infos = {n: run.body_info[n] for n in names}
    col = collisions(contacts.filter(pl.col("kind") == "body"), states, infos)
    if col.is_empty() and len(names) >= 2 and expects_collision(run):
        col = no_collision_rows(
            run.run_id,
            states,
            infos,
            f"no contact between the bodies in the {duration_s(states):.4g} s logged: the "
            "collision never happened, so 'after' (last logged state) equals 'before'",
        )
    summary = summary_row(
        run,
        states=states,
        energy=energy,
        phases=phases,
        bounces=bnc,
        collisions=col,
        ground=bool(ground.surfaces),
    )
    return RunAnalysis(run, states, contacts, energy, phases, bnc, col, summary, ground)


def contact_times(contacts: pl.DataFrame, rows: pl.DataFrame) -> pl.Series:
    """t_ns of every logged row inside any contact (chatter merged), sorted."""
    if contacts.is_empty() or rows.is_empty():
        return pl.Series("t_ns", [], dtype=pl.Int64)
    row, t_ns = rows["row"].to_numpy(), rows["t_ns"].to_numpy()
    first, last = contacts["first_row"].to_numpy(), contacts["last_row"].to_numpy()
    size = int(max(row.max(), last.max())) + 2
    cover = np.zeros(size, dtype=np.int64)  # +1 where a contact starts, -1 after it ends
    np.add.at(cover, first, 1)
    np.add.at(cover, last + 1, -1)
    inside = np.cumsum(cover)[row] > 0
    return pl.Series("t_ns", np.sort(t_ns[inside]), dtype=pl.Int64)


def duration_s(states: pl.DataFrame) -> float:
    """Logged duration in s (0 when nothing was logged)."""
    return float(states["t_s"].max() or 0.0) if states.height else 0.0


def no_bounce_reason(body: str, on_ground: pl.DataFrame, states: pl.DataFrame) -> str:
    """Why a body on a run with a ground has no bounce."""
    mine = on_ground.filter(pl.col("body") == body).sort("first_row")
    if mine.is_empty():
        return f"no contact with the ground in the {duration_s(states):.4g} s logged"
    first = mine.row(0, named=True)
    if first["row_b"] is None:
        return (
            f"at rest, sliding or rolling on {first['other']} from the first logged step: "
            "no impact, no bounce"
        )
    return (
        f"touches {first['other']} no faster than v_min = {first['v_min_mps']:.3g} m/s and "
        "stays: a resting, sliding or rolling contact, no bounce"
    )
