"""Contact episodes as the recorder found them at every step, classified; e by velocity and work."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import polars as pl

from impactlab import physics
from impactlab.analyze.measure.states import at_times
from impactlab.logs.decode import IMPACT_SCHEMA
from impactlab.logs.load import RunLog
from impactlab.logs.messages import WORK_FIELDS
from impactlab.physics import min_impact_speed

KINDS = ("ground", "body", "other")
"""An episode's kind: a rigid body on a surface, two rigid bodies, anything else (a flex)."""


def e_velocity() -> pl.Expr:
    """`physics.e_velocity` of an episode's columns."""
    return physics.e_velocity(pl.col("v_in_mps"), pl.col("v_out_mps"))


def e_energy() -> pl.Expr:
    """`physics.e_energy` of an episode's columns."""
    return physics.e_energy(pl.col("work_c_J"), pl.col("work_r_J"), ~pl.col("open"))


def episodes(runs: Sequence[RunLog], rows: pl.DataFrame) -> pl.DataFrame:
    """Every episode of the runs, one row each, with the logged rows it covers.

    Args:
        runs: decoded logs (format 3: they carry `RunLog.impacts`).
        rows: (run_id, t_ns, row): each run's logged rows (`states.states_long`).

    Returns:
        (run_id, kind, body, other, start_t_ns, end_t_ns, impact_t_s, release_t_s,
        v_in_mps, v_out_mps, v_min_mps, impact (arrived at v_min or faster, after the start),
        initial (touching at the start), open, work_c_J, work_r_J, work_f_J, peak_force_N,
        impulse_Ns, max_penetration_m, e_note (`e_note`: why e_velocity is outside [0, 1],
        "" when it is not), the normal from the surface or `body` to the other
        side at the first and last step (nx_in .. nz_out) and the contact point then (px_in ..
        pz_out), first_row, last_row (the logged rows inside it), and the sides' states
        `s1_*`, `s2_*` as recorded), by run and time.
    """
    v_min = {
        run.run_id: min_impact_speed(float(np.linalg.norm(run.gravity)), run.timestep_s)
        for run in runs
    }
    empty = pl.DataFrame(schema=IMPACT_SCHEMA)  # the columns even when no run has an episode
    raw = pl.concat([empty, *(run.impacts for run in runs)], how="vertical_relaxed")
    ground = (pl.col("kind1") == "body") & (pl.col("kind2") == "surface")
    body = (pl.col("kind1") == "body") & (pl.col("kind2") == "body")
    flip = pl.when(ground).then(-1.0).otherwise(1.0)  # normals from the surface to the body
    out = raw.select(
        "run_id",
        pl.when(ground)
        .then(pl.lit("ground"))
        .when(body)
        .then(pl.lit("body"))
        .otherwise(pl.lit("other"))
        .alias("kind"),
        pl.col("side1").alias("body"),
        pl.col("side2").alias("other"),
        pl.col("onset_ns").alias("start_t_ns"),
        pl.col("release_ns").alias("end_t_ns"),
        (pl.col("onset_ns") / 1e9).alias("impact_t_s"),
        (pl.col("release_ns") / 1e9).alias("release_t_s"),
        "v_in_mps",
        "v_out_mps",
        pl.col("run_id").replace_strict(v_min, return_dtype=pl.Float64).alias("v_min_mps"),
        (pl.col("onset_ns") == 0).alias("initial"),
        "open",
        pl.col("work_compression_J").alias("work_c_J"),
        pl.col("work_restitution_J").alias("work_r_J"),
        pl.col("work_friction_J").alias("work_f_J"),
        "peak_force_N",
        "impulse_Ns",
        "max_penetration_m",
        *[(flip * pl.col(f"n{c}_out")).alias(f"n{c}_out") for c in "xyz"],
        *[(flip * pl.col(f"n{c}_in")).alias(f"n{c}_in") for c in "xyz"],
        pl.col("^p[xyz]_(in|out)$"),
        pl.col("^s[12]_(in|out)_.*$"),
    ).with_columns(
        (~pl.col("initial") & (pl.col("v_in_mps") <= -pl.col("v_min_mps"))).alias("impact")
    )
    out = out.sort("run_id", "start_t_ns", maintain_order=True)
    odd = (~pl.col("open") & ~pl.col("initial") & ~e_velocity().is_between(0, 1)).fill_null(False)
    notes = np.full(out.height, "", dtype=object)
    by_id = {run.run_id: run for run in runs}
    budgets: dict[str, tuple[np.ndarray, dict[str, np.ndarray]]] = {}
    energetic = out.select(e_energy()).to_series()
    for i in out.select(odd).to_series().arg_true().to_list():
        row = out.row(i, named=True) | {"e_energy": energetic[i]}
        if row["run_id"] not in budgets:
            budgets[row["run_id"]] = cumulative_works(by_id[row["run_id"]])
        notes[i] = e_note(row, *budgets[row["run_id"]])
    return _with_rows(out.with_columns(pl.Series("e_note", notes, dtype=pl.String)), rows)


def cumulative_works(run: RunLog) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The run's logged times (ns) and, at each, the work done since the start by each kind
    of force of its budget (J), gravity's as m g . x summed over the bodies."""
    t = run.work["t_ns"].to_numpy()
    works = {k: run.work[k].to_numpy() for k in WORK_FIELDS}
    works["gravity"] = np.zeros(t.size)
    for name, frame in run.bodies.items():
        if name in run.body_info:
            xyz = np.column_stack([at_times(t, frame, c) for c in "xyz"])
            works["gravity"] += run.body_info[name].mass * (xyz @ run.gravity)
    return t, works


def e_note(episode: dict[str, Any], t: np.ndarray, cumulative: dict[str, np.ndarray]) -> str:
    """Why a closed episode's e_velocity is outside [0, 1], from the budget (`cumulative_works`)
    over the logged rows around it: this contact's normal work (and its `e_energy`, None where
    undefined), then the work of every other kind of force then, largest first (other
    contacts: the run's contact work less this one's), and the largest input of energy."""
    start, end = int(episode["start_t_ns"]), int(episode["end_t_ns"])
    first = max(int(np.searchsorted(t, start, side="right")) - 1, 0)
    last = min(int(np.searchsorted(t, end, side="left")), t.size - 1)
    done = {k: float(v[last] - v[first]) if t.size else np.nan for k, v in cumulative.items()}
    own = episode["work_c_J"] + episode["work_r_J"]
    contacts = done.pop("contact_normal") + done.pop("contact_friction")
    works = {"other contacts": contacts - own - episode["work_f_J"]}
    works |= {k.replace("_", " "): w for k, w in done.items()}
    unknown = [k for k, w in works.items() if not np.isfinite(w)]  # damaged: not quoted
    works = {k: w for k, w in works.items() if k not in unknown}
    tolerance = 1e-9 + 1e-6 * max([abs(own), *(abs(w) for w in works.values())])
    acting = sorted((k for k in works if abs(works[k]) > tolerance), key=lambda k: -abs(works[k]))
    listed = ", ".join(f"{k} {works[k]:+.3g} J" for k in acting) or "none did work"
    inputs = {"this contact": own} | {k: works[k] for k in acting}
    fed = max(inputs, key=lambda k: inputs[k])
    source = (
        f"the largest input: {fed}"
        if inputs[fed] > tolerance
        else "no force put energy in: the speed came from the bodies' own motion (their "
        "rotation, or momentum passed along their joints)"
    )
    if not works:  # no budget logged around it: nothing to quote
        listed, source = "not in the log", "where the energy came from is unknown"
    elif unknown and inputs[fed] <= tolerance:
        source = f"no force quoted put energy in; unknown: {', '.join(unknown)}"
    e = physics.e_velocity(episode["v_in_mps"], episode["v_out_mps"])
    span = f"From {t[first] / 1e9:.6g} to {t[last] / 1e9:.6g} s" if t.size else "Over the contact"
    return (
        f"e_velocity {e:.3g} is outside [0, 1]: a ratio of the contact point's speeds, not a "
        f"restitution. {span} this contact's normal force did {own:+.3g} J"
        + (f" (e_energy {episode['e_energy']:.3g})" if episode["e_energy"] is not None else "")
        + f"; the model's other forces: {listed}; {source}"
    )


def _with_rows(frame: pl.DataFrame, rows: pl.DataFrame) -> pl.DataFrame:
    """`first_row` and `last_row`: the first logged row at or after the start and the last
    before the release (first > last when the episode lies between two logged rows)."""
    first = np.empty(frame.height, np.int64)
    last = np.empty(frame.height, np.int64)
    logged = {
        k[0]: f["t_ns"].to_numpy() for k, f in rows.partition_by("run_id", as_dict=True).items()
    }
    ids = frame["run_id"].to_list()
    start, end = frame["start_t_ns"].to_numpy(), frame["end_t_ns"].to_numpy()
    for i, r in enumerate(ids):
        t = logged.get(r, np.empty(0, np.int64))
        first[i] = np.searchsorted(t, start[i], side="left")
        last[i] = np.searchsorted(t, end[i], side="left") - 1
    return frame.with_columns(pl.Series("first_row", first), pl.Series("last_row", last))
