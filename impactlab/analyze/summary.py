"""A run's row of the runs table: identity, state of the log, and headline results.

Bounce headlines (drop height, first impact, mean e) describe one body on one surface; a run
with bounces of several bodies or on several surfaces has them empty, with a note, and its
numbers per body and surface are in the bounces table: bodies with different contacts are
never averaged together.
"""

from __future__ import annotations

from typing import Any

import polars as pl

from impactlab.logs.load import RunLog


def summary_row(
    run: RunLog,
    *,
    states: pl.DataFrame,
    energy: pl.DataFrame,
    phases: pl.DataFrame,
    bounces: pl.DataFrame,
    collisions: pl.DataFrame,
    ground: bool,
) -> dict[str, Any]:
    """The run's row of the runs table (see the module docstring).

    Args:
        run: the decoded log; the other frames are its analysis (`RunAnalysis`).
        ground: whether the run has ground surfaces.
    """
    total = energy.filter(pl.col("body") == "total").sort("t_ns")
    e0 = total["total_J"][0] if total.height else None
    e1 = total["total_J"][-1] if total.height else None
    flights = phases.filter(pl.col("kind") == "flight")
    contacts = phases.filter(pl.col("kind") == "contact")
    bounced = bounces.filter(pl.col("bounce").is_not_null())
    pairs = bounced.select("body", "surface").unique()
    single = pairs.height == 1
    good = bounced.filter(pl.col("complete"))
    first = bounced.filter(pl.col("bounce") == 1) if single else bounced.clear()
    col = collisions.head(1)
    notes = [n for n in bounces.filter(pl.col("bounce").is_null())["note"].to_list() if n]
    if pairs.height > 1:
        notes.append(
            f"bounces of {pairs.height} body-surface pairs: e per pair in the bounces table"
        )
    if col.height and not col["complete"][0] and col["note"][0]:
        notes.append(col["note"][0])
    scale = abs(e0) if e0 else None

    def c(name: str) -> Any:
        return col[name][0] if col.height else None

    def f(name: str) -> Any:
        return first[name][0] if first.height else None

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
        "log_every": run.log_every,
        "duration_s": float(states["t_s"].max() or 0.0) if states.height else 0.0,
        "n_bodies": len(run.bodies),
        "ground": ground,
        "sweep": "{}" if "sweep" in run.checked.problems else run.meta.get("sweep", "{}"),
        "energy_initial_J": e0,
        "energy_final_J": e1,
        "energy_loss_frac": (e0 - e1) / e0 if e0 else None,
        "flight_drift_max_J": flights["drift_J"].abs().max() if flights.height else None,
        "flight_drift_max_rel": (flights["max_dev_J"].max() / scale)
        if flights.height and scale
        else None,
        "contact_loss_sum_J": contacts["loss_J"].sum() if contacts.height else 0.0,
        "mujoco_diff_max_J": total["mujoco_diff_J"].abs().max() if total.height else None,
        "drop_height_m": f("apex_before_m"),
        "n_bounces": bounced.height,
        "n_bounces_complete": good.height,
        "first_impact_speed_mps": -f("v_in_mps") if f("v_in_mps") is not None else None,
        "e_velocity_first": f("e_velocity"),
        "e_velocity_mean": good["e_velocity"].mean() if single and good.height else None,
        "e_apex_mean": good["e_apex"].mean() if single and good.height else None,
        "n_collisions": int(collisions["collision"].count()),
        "e_collision": c("e_measured"),
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
