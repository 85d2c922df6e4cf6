"""Flight and contact phases of runs and their energy budget: the work of each kind of force."""

from __future__ import annotations

import polars as pl

from impactlab.logs.messages import WORK_FIELDS

WORK_COLUMNS = tuple(f"work_{kind}_J" for kind in WORK_FIELDS)
"""The budget's works, J: one column per kind of force (`schemas/impactlab.proto`'s Work)."""


def energy_phases(budget: pl.DataFrame, in_contact: pl.Series) -> pl.DataFrame:
    """Flight and contact phases of one or more runs with their energy budget.

    A phase runs from its first logged row to the first row of the next phase (the run's
    last row for the last one), so the phases of a run tile it: the budget's energy change
    over each is the sum of the works done in it plus the integrator's residual.

    Args:
        budget: the runs' rows (run_id, t_ns, t_s, energy_J: the budget's energy, MuJoCo's
            kinetic energy plus the gravitational potential energy; `WORK_COLUMNS`: the work
            done so far), each run's rows together and by time.
        in_contact: per row, whether it lies inside a contact episode.

    Returns:
        One row per phase: (run_id, phase, kind = "flight" | "contact", start_t_s, end_t_s,
        e_start_J, e_end_J, change_J, `WORK_COLUMNS`, residual_J, max_dev_J (the largest
        |residual| within the phase), open (the last phase, in contact)); phases numbered
        from 0 in each run.
    """
    done = sum(pl.col(c) for c in WORK_COLUMNS)
    # a new phase where the run or the contact state changes (each run's rows together)
    frame = (
        budget.hstack([in_contact.alias("in_contact")])
        .with_columns(
            pl.struct("run_id", "in_contact").rle_id().alias("_phase"),
            (pl.col("energy_J") - done).alias("_unexplained"),
        )
        .with_columns(
            (pl.col("_phase") - pl.col("_phase").min().over(pl.col("run_id").rle_id())).alias(
                "phase"
            )
        )
    )
    first = frame.group_by("_phase", maintain_order=True).agg(
        pl.col("run_id").first(),
        pl.col("phase").first(),
        pl.col("in_contact").first(),
        pl.col("t_s").first().alias("start_t_s"),
        pl.col("energy_J").first().alias("e_start_J"),
        *[pl.col(c).first().alias(f"_{c}") for c in WORK_COLUMNS],
        pl.col("_unexplained").first().alias("_u0"),
        pl.col("_unexplained").max().alias("_umax"),
        pl.col("_unexplained").min().alias("_umin"),
        pl.col("t_s").last().alias("_last_t"),
        pl.col("energy_J").last().alias("_last_e"),
        *[pl.col(c).last().alias(f"_last_{c}") for c in WORK_COLUMNS],
    )
    same_run = pl.col("run_id").shift(-1) == pl.col("run_id")

    def next_or_last(column: str, last: str) -> pl.Expr:
        return pl.when(same_run).then(pl.col(column).shift(-1)).otherwise(pl.col(last))

    return (
        first.with_columns(
            next_or_last("start_t_s", "_last_t").alias("end_t_s"),
            next_or_last("e_start_J", "_last_e").alias("e_end_J"),
            *[
                (next_or_last(f"_{c}", f"_last_{c}") - pl.col(f"_{c}")).alias(c)
                for c in WORK_COLUMNS
            ],
        )
        .with_columns(
            (pl.col("e_end_J") - pl.col("e_start_J")).alias("change_J"),
        )
        .with_columns(
            (pl.col("change_J") - pl.sum_horizontal(WORK_COLUMNS)).alias("residual_J"),
            pl.max_horizontal(
                (pl.col("_umax") - pl.col("_u0")).abs(), (pl.col("_umin") - pl.col("_u0")).abs()
            ).alias("max_dev_J"),
            (pl.col("in_contact") & ~same_run).alias("open"),
        )
        .select(
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
            "change_J",
            *WORK_COLUMNS,
            "residual_J",
            "max_dev_J",
            "open",
        )
    )
