"""Flight and contact phases of runs and their energy budget.

Flight phases are the runs of logged rows in no contact (contacts merged across chatter);
the energy of the run should stay constant there (`drift_J`). Each contact phase loses
`loss_J`: the energy at the last logged row before it minus that at the first logged row
after it, so that E(start) - E(end) = sum(loss_J) - sum(drift_J) exactly.
"""

from __future__ import annotations

import numpy as np
import polars as pl


def energy_phases(total: pl.DataFrame, in_contact: pl.Series) -> pl.DataFrame:
    """Flight and contact phases of one or more runs with their energy change.

    Args:
        total: the runs' "total" energy rows (run_id, t_ns, t_s, total_J), each run's rows
            together and sorted by time.
        in_contact: per row of `total`, whether it lies inside a contact (chatter merged).

    Returns:
        One row per phase: (run_id, phase, kind = "flight" | "contact", start_t_s, end_t_s,
        e_start_J, e_end_J, drift_J (flight: E(end) - E(start)), max_dev_J (flight: max
        |E - E(start)|), loss_J (contact: E(last row before) - E(first row after); up to the
        last logged row when the contact is still open), open); phases numbered from 0 in
        each run.
    """
    phases = (
        total.select("run_id", "t_s", "total_J")
        .hstack([in_contact.alias("in_contact"), *_phase_ids(total["run_id"], in_contact)])
        .group_by("_phase", maintain_order=True)
        .agg(
            pl.col("run_id").first(),
            pl.col("phase").first(),
            pl.col("in_contact").first(),
            pl.col("t_s").first().alias("start_t_s"),
            pl.col("t_s").last().alias("end_t_s"),
            pl.col("total_J").first().alias("e_start_J"),
            pl.col("total_J").last().alias("e_end_J"),
            (pl.col("total_J") - pl.col("total_J").first()).abs().max().alias("max_dev_J"),
        )
    )
    return phases.select(
        "run_id",
        "phase",
        pl.when(pl.col("in_contact"))
        .then(pl.lit("contact"))
        .otherwise(pl.lit("flight"))
        .alias("kind"),
        "start_t_s",
        "end_t_s",
        "e_start_J",
        "e_end_J",
        pl.when(~pl.col("in_contact"))
        .then(pl.col("e_end_J") - pl.col("e_start_J"))
        .alias("drift_J"),
        pl.when(~pl.col("in_contact")).then(pl.col("max_dev_J")).alias("max_dev_J"),
        pl.when(pl.col("in_contact"))
        .then(
            pl.col("e_end_J").shift(1).over("run_id").fill_null(pl.col("e_start_J"))
            - pl.col("e_start_J").shift(-1).over("run_id").fill_null(pl.col("e_end_J"))
        )
        .alias("loss_J"),
        (pl.col("in_contact") & (pl.col("phase") == pl.col("phase").max().over("run_id"))).alias(
            "open"
        ),
    )


def _phase_ids(run_id: pl.Series, in_contact: pl.Series) -> list[pl.Series]:
    """Each row's phase over all runs (`_phase`) and within its run (`phase`, from 0): a
    new phase where the run or the contact state changes (each run's rows together)."""
    inside = in_contact.to_numpy().astype(bool)
    n = inside.size
    change = np.ones(n, dtype=bool)
    change[1:] = inside[1:] != inside[:-1]
    lengths = run_id.rle().struct.field("len").to_numpy() if n else np.zeros(0, np.int64)
    starts = np.cumsum(lengths) - lengths
    change[starts] = True
    every = np.cumsum(change) - 1
    first = np.repeat(every[starts], lengths)
    return [pl.Series("_phase", every), pl.Series("phase", every - first, dtype=pl.UInt32)]
