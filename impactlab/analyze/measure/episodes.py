"""Contact episodes as the recorder found them at every step, classified; e by velocity and work."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import polars as pl

from impactlab import physics
from impactlab.logs.decode import IMPACT_SCHEMA
from impactlab.logs.load import RunLog
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
        impulse_Ns, max_penetration_m, the normal from the surface or `body` to the other
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
    return _with_rows(out.sort("run_id", "start_t_ns", maintain_order=True), rows)


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
