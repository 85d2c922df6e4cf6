"""Analysis of one run: every quantity frame, and the run's one-row summary."""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import polars as pl

from impactlab.analyze.bounces import bounces, no_bounce_row
from impactlab.analyze.collisions import collisions, no_collision_rows
from impactlab.analyze.contacts import logged_step_ns, run_intervals, states_long
from impactlab.analyze.energy import energy_phases, run_energy
from impactlab.errors import LogError
from impactlab.logs.load import RunLog


@dataclass
class RunAnalysis:
    """Everything computed for one run.

    Attributes:
        run: the decoded log.
        states: every body's state (`states_long`).
        intervals: contact intervals of every pair.
        energy: energy per body and total ("total" rows), full resolution.
        phases: flight and contact phases with energy drift and loss.
        bounces: one row per bounce on the plane (one row with the reason when none).
        collisions: one row per body-body contact (rows with the reason when none).
        summary: the run's row of the runs table.
    """

    run: RunLog
    states: pl.DataFrame
    intervals: pl.DataFrame
    energy: pl.DataFrame
    phases: pl.DataFrame
    bounces: pl.DataFrame
    collisions: pl.DataFrame
    summary: dict[str, Any]


def analyze_run(run: RunLog) -> RunAnalysis:
    """Compute energy, bounces, collisions and the summary row of one decoded log.

    Raises:
        LogError: the log lacks the run metadata the analysis needs (timestep, bodies).
    """
    if "timestep_s" not in run.meta or "bodies" not in run.meta:
        raise LogError(
            str(run.path), "no impactlab.run metadata (timestep, bodies): cannot analyze"
        )
    step_ns = logged_step_ns(run)
    states = states_long(run)
    intervals = run_intervals(run)
    energy = run_energy(run)
    total = energy.filter(pl.col("body") == "total").sort("t_ns")
    contact_times = intervals_steps(intervals, step_ns)
    phases = energy_phases(total, contact_times)
    names = [n for n in run.body_info if n in run.bodies]
    bnc = bounces(intervals, states, energy, bodies=names, gravity=run.gravity, step_ns=step_ns)
    if bnc.is_empty() and run.plane_z is not None:
        bnc = no_bounce_row(run.run_id, no_bounce_reason(run))
    col = collisions(intervals, states, {n: run.body_info[n] for n in names}, step_ns=step_ns)
    if col.is_empty() and len(names) >= 2:
        col = no_collision_rows(
            run.run_id,
            states,
            {n: run.body_info[n] for n in names},
            f"no contact between the bodies in the {duration_s(states):.4g} s logged: the "
            "collision never happened, so 'after' (last logged state) equals 'before'",
        )
    analysis = RunAnalysis(run, states, intervals, energy, phases, bnc, col, {})
    analysis.summary = summary_row(analysis)
    return analysis


def intervals_steps(intervals: pl.DataFrame, step_ns: int) -> pl.Series:
    """t_ns of every logged step inside any contact interval."""
    if intervals.is_empty():
        return pl.Series("t_ns", [], dtype=pl.Int64)
    return (
        intervals.select(
            pl.int_ranges(pl.col("start_t_ns"), pl.col("end_t_ns") + 1, step_ns).alias("t_ns")
        )
        .explode("t_ns")
        .get_column("t_ns")
        .unique()
        .sort()
    )


def duration_s(states: pl.DataFrame) -> float:
    """Logged duration in s (0 when nothing was logged)."""
    return float(states["t_s"].max() or 0.0) if states.height else 0.0


def no_bounce_reason(run: RunLog) -> str:
    """Why a run with a plane has no bounce."""
    if not run.bodies:
        return "no body state in the log"
    return f"no contact with the plane in the {duration_s(states_long(run)):.4g} s logged"


def summary_row(a: RunAnalysis) -> dict[str, Any]:
    """The run's row of the runs table: identity, state of the log, and headline results."""
    run = a.run
    total = a.energy.filter(pl.col("body") == "total").sort("t_ns")
    e0 = total["total_J"][0] if total.height else None
    e1 = total["total_J"][-1] if total.height else None
    flights = a.phases.filter(pl.col("kind") == "flight")
    contacts = a.phases.filter(pl.col("kind") == "contact")
    good = a.bounces.filter(pl.col("complete"))
    first = a.bounces.filter(pl.col("bounce") == 1)
    col = a.collisions.head(1)
    notes = []
    if a.bounces.height and a.bounces["bounce"].is_null().all():
        notes.append(a.bounces["note"][0])
    if col.height and not col["complete"][0]:
        notes.append(col["note"][0])
    scale = abs(e0) if e0 else None

    def c(name: str) -> Any:
        return col[name][0] if col.height else None

    return {
        "run_id": run.run_id,
        "experiment": run.experiment,
        "description": run.meta.get("description", ""),
        "file": str(run.path),
        "partial": run.partial,
        "problems": "; ".join(run.problems),
        "outcome": run.outcome,
        "reason": run.meta.get("reason", ""),
        "warnings": "; ".join(json.loads(run.meta.get("warnings", "[]") or "[]")),
        "timestep_s": run.timestep_s,
        "log_every": int(run.meta.get("log_every", "1") or 1),
        "duration_s": duration_s(a.states),
        "n_bodies": len(run.bodies),
        "plane": run.plane_z is not None,
        "sweep": run.meta.get("sweep", "{}"),
        "energy_initial_J": e0,
        "energy_final_J": e1,
        "energy_loss_frac": (e0 - e1) / e0 if e0 else None,
        "flight_drift_max_J": flights["drift_J"].abs().max() if flights.height else None,
        "flight_drift_max_rel": (flights["max_dev_J"].max() / scale)
        if flights.height and scale
        else None,
        "contact_loss_sum_J": contacts["loss_J"].sum() if contacts.height else 0.0,
        "mujoco_diff_max_J": total["mujoco_diff_J"].abs().max() if total.height else None,
        "drop_height_m": first["apex_before_m"][0] if first.height else None,
        "n_bounces": int(a.bounces["bounce"].count()),
        "n_bounces_complete": good.height,
        "first_impact_speed_mps": -first["v_in_mps"][0]
        if first.height and first["v_in_mps"][0] is not None  # None: in contact from the start
        else None,
        "e_velocity_first": first["e_velocity"][0] if first.height else None,
        "e_velocity_mean": good["e_velocity"].mean() if good.height else None,
        "e_apex_mean": good["e_apex"].mean() if good.height else None,
        "n_collisions": int(a.collisions["collision"].count()),
        "e_collision": c("e_measured"),
        "v1n_before_mps": c("v1n_before_mps"),
        "v2n_before_mps": c("v2n_before_mps"),
        "v1n_after_mps": c("v1n_after_mps"),
        "v2n_after_mps": c("v2n_after_mps"),
        "v1n_after_elastic_mps": c("v1n_after_elastic_mps"),
        "v2n_after_elastic_mps": c("v2n_after_elastic_mps"),
        "momentum_rel_change": c("momentum_rel_change"),
        "collision_ke_loss_frac": c("ke_loss_frac"),
        "note": "; ".join(n for n in notes if n),
    }
