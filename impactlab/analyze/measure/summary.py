"""A run's row of the runs table: identity, state of the log, and headline results."""

from __future__ import annotations

from typing import Any

import numpy as np
import polars as pl

from impactlab.analyze.measure.phases import WORK_COLUMNS
from impactlab.logs.load import RunLog

NO_ROWS: dict[str, Any] = {
    "n_flights": 0,
    "n_contacts": 0,
    "loss_sum": 0.0,
    "n_bounces": 0,
    "n_pairs": 0,
    "n_good": 0,
    "notes": [],
}
"""The aggregates `run_aggregates` gives a run without energy, phase or bounce rows (any
other aggregate: None)."""


NEGLIGIBLE_ENERGY_J = 1e-9
"""An energy (or a work, a change of it) at or below this many joules, or 1e-9 of the initial
energy, is zero: the budget closes on MuJoCo's energy to about 1e-11 J."""


def run_aggregates(
    total: pl.DataFrame, phases: pl.DataFrame, bounces: pl.DataFrame
) -> dict[str, dict[str, Any]]:
    """The aggregates of every run in the frames, by run id, in one group-by per frame.

    Args:
        total: the runs' "total" energy rows, each run's by time.
        phases: the runs' energy phases; bounces: their bounce tables.
    """
    flight, contact = pl.col("kind") == "flight", pl.col("kind") == "contact"
    e = total.group_by("run_id", maintain_order=True).agg(
        pl.col("total_J").first().alias("energy_start"),
        pl.col("total_J").last().alias("energy_end"),
        pl.col("mujoco_diff_J").abs().max().alias("mujoco_diff_max"),
    )
    drift = pl.col("residual_J").filter(flight)  # in flight the residual is the drift
    worst = drift.abs()  # the flight with the largest |drift|
    contact_work = pl.col("work_contact_normal_J") + pl.col("work_contact_friction_J")
    p = phases.group_by("run_id", maintain_order=True).agg(
        flight.sum().alias("n_flights"),
        drift.abs().max().alias("drift_max"),
        drift.sort_by(worst).last().alias("drift_worst"),
        (pl.col("end_t_s") - pl.col("start_t_s"))
        .filter(flight)
        .sort_by(worst)
        .last()
        .alias("drift_worst_T"),
        pl.col("max_dev_J").filter(flight).max().alias("dev_max"),
        contact.sum().alias("n_contacts"),
        (-contact_work).sum().alias("loss_sum"),
        pl.col("residual_J").sum().alias("residual"),
        *[pl.col(c).sum() for c in WORK_COLUMNS],
    )
    bounced = pl.col("bounce").is_not_null()
    good = bounced & pl.col("complete")
    first = bounced & (pl.col("bounce") == 1)
    b = bounces.group_by("run_id", maintain_order=True).agg(
        bounced.sum().alias("n_bounces"),
        pl.struct("body", "surface").filter(bounced).n_unique().alias("n_pairs"),
        good.sum().alias("n_good"),
        *[pl.col(c).filter(first).first() for c in ("apex_before_m", "v_in_mps", "e_velocity")],
        pl.col("e_velocity").filter(good).mean().alias("e_velocity_mean"),
        pl.col("e_apex").filter(good).mean().alias("e_apex_mean"),
        pl.col("note").filter(~bounced).alias("notes"),
    )
    out: dict[str, dict[str, Any]] = {}
    for frame in (e, p, b):
        for row in frame.to_dicts():
            out.setdefault(row.pop("run_id"), {}).update(row)
    return out


def duration_s(states: pl.DataFrame) -> float:
    """Logged duration in s (0 when nothing was logged)."""
    return float(states.select(pl.col("t_s").max()).item() or 0.0) if states.height else 0.0


def predicted_drift(run: RunLog, flight_s: float | None, forced: bool) -> float | None:
    """The energy drift, J, the run's integrator gives its free bodies in a flight of
    `flight_s`: -M g^2 h T with h the log's half step (`RunLog.half_step_s`), so -M g^2 dt T / 2
    for MuJoCo's semi-implicit integrators (positions advance with the new velocity), 0 for
    RK4 (exact on a parabola); None when the flight is not known, or the formula does not hold:
    a body that is not free, or a force besides gravity and the contacts that does work
    (`forced`)."""
    if flight_s is None or forced:
        return None
    if any(info.motion != "free" for info in run.body_info.values()):
        return None
    mass = sum(info.mass for name, info in run.body_info.items() if name in run.bodies)
    g2 = float(np.dot(run.gravity, run.gravity))
    return -mass * g2 * run.half_step_s * flight_s


def summary_row(
    run: RunLog,
    *,
    aggregates: dict[str, dict[str, Any]],
    states: pl.DataFrame,
    collisions: pl.DataFrame,
    ground: bool,
) -> dict[str, Any]:
    """The run's row of the runs table (see the module docstring).

    Args:
        run: the decoded log; `states` and `collisions` are its analysis (`RunAnalysis`).
        aggregates: the runs' aggregates of their energy, phases and bounces (`run_aggregates`).
        ground: whether the run has ground surfaces.
    """
    agg = NO_ROWS | aggregates.get(run.run_id, {})
    energy_start, energy_end = agg.get("energy_start"), agg.get("energy_end")
    single = agg["n_pairs"] == 1
    col = collisions.row(0, named=True) if collisions.height else None
    notes = [n for n in agg["notes"] if n]
    if agg["n_pairs"] > 1:
        notes.append(
            f"bounces of {agg['n_pairs']} body-surface pairs: e per pair in the bounces table"
        )
    if col is not None and not col["complete"] and col["note"]:
        notes.append(col["note"])
    scale = abs(energy_start) if energy_start else None
    contact = ("work_contact_normal_J", "work_contact_friction_J", "work_solver_J")
    forced = any(  # a force besides gravity and the contacts' works: no free-flight formula
        abs(agg.get(c) or 0.0) > NEGLIGIBLE_ENERGY_J * max(1.0, scale or 0.0)
        for c in WORK_COLUMNS
        if c not in contact
    )

    def c(name: str) -> Any:
        return col[name] if col is not None else None

    def f(name: str) -> Any:
        return agg.get(name) if single else None

    return {
        "run_id": run.run_id,
        "experiment": run.experiment,
        "description": run.meta.get("description", ""),
        "file": str(run.path),
        "partial": run.partial,
        "problems": "; ".join(run.problems),
        "outcome": run.outcome,
        "reason": run.meta.get("reason", ""),
        "warnings": "; ".join(run.warnings),
        "timestep_s": run.timestep_s,
        "integrator": run.integrator,
        "log_every": run.log_every,
        "duration_s": duration_s(states),
        "n_bodies": len(run.bodies),
        "ground": ground,
        "sweep": "{}" if "sweep" in run.checked.problems else run.meta.get("sweep", "{}"),
        "energy_initial_J": energy_start,
        "energy_final_J": energy_end,
        "energy_loss_frac": (energy_start - energy_end) / energy_start if energy_start else None,
        "flight_drift_max_J": agg.get("drift_max") if agg["n_flights"] else None,
        "flight_drift_max_rel": (agg.get("dev_max") / scale)
        if agg["n_flights"] and scale
        else None,
        "flight_drift_J": agg.get("drift_worst") if agg["n_flights"] else None,
        "flight_drift_predicted_J": predicted_drift(run, agg.get("drift_worst_T"), forced)
        if agg["n_flights"]
        else None,
        "contact_loss_sum_J": agg["loss_sum"],
        **{c: agg.get(c) for c in WORK_COLUMNS},
        "residual_J": agg.get("residual"),
        "mujoco_diff_max_J": agg.get("mujoco_diff_max"),
        "drop_height_m": f("apex_before_m"),
        "n_bounces": agg["n_bounces"],
        "n_bounces_complete": agg["n_good"],
        "first_impact_speed_mps": -f("v_in_mps") if f("v_in_mps") is not None else None,
        "e_velocity_first": f("e_velocity"),
        "e_velocity_mean": agg.get("e_velocity_mean") if single and agg["n_good"] else None,
        "e_apex_mean": agg.get("e_apex_mean") if single and agg["n_good"] else None,
        "n_collisions": collisions.height - collisions["collision"].null_count(),
        "e_collision": c("e_velocity"),
        "v1n_before_mps": c("v1n_before_mps"),
        "v2n_before_mps": c("v2n_before_mps"),
        "v1n_after_mps": c("v1n_after_mps"),
        "v2n_after_mps": c("v2n_after_mps"),
        "v1n_after_elastic_mps": c("v1n_after_elastic_mps"),
        "v2n_after_elastic_mps": c("v2n_after_elastic_mps"),
        "momentum_rel_change": c("momentum_rel_change"),
        "collision_ke_loss_frac": c("ke_loss_frac"),
        "note": "; ".join(dict.fromkeys(notes)),
    }
