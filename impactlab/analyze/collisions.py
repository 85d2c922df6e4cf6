"""Body-body collisions: velocities, momentum and kinetic energy before and after, measured e,
and the analytic 1D outcome along the line of centres.

The normal n is the unit vector from body1's centre to body2's at the first logged step in
contact. "Before" is the state at the last logged step before the contact interval, "after" the
first logged step after it. v1n, v2n are the velocities along n; the measured
e = -(v2n' - v1n') / (v2n - v1n). The analytic outcome for restitution e (notes, physics.md):
v1' = (m1 v1 + m2 v2 + m2 e (v2 - v1)) / (m1 + m2), v2' = (m1 v1 + m2 v2 + m1 e (v1 - v2)) /
(m1 + m2), kinetic energy lost (1 - e^2) m1 m2 (v1 - v2)^2 / (2 (m1 + m2)). The relative momentum
change is |p' - p| / (|m1 v1| + |m2 v2|) (not |p|, which can be zero).
"""

from __future__ import annotations

import polars as pl

from impactlab.analyze.contacts import state_at
from impactlab.logs.load import BodyInfo
from impactlab.physics import collision_after

COLLISION_SCHEMA: dict[str, pl.DataType] = {
    "run_id": pl.String,
    "body1": pl.String,
    "body2": pl.String,
    "collision": pl.Int64,
    "m1_kg": pl.Float64,
    "m2_kg": pl.Float64,
    "impact_t_s": pl.Float64,
    "release_t_s": pl.Float64,
    "duration_s": pl.Float64,
    "nx": pl.Float64,
    "ny": pl.Float64,
    "nz": pl.Float64,
    **{
        f"{v}{c}_{w}_mps": pl.Float64
        for w in ("before", "after")
        for v in ("v1", "v2")
        for c in "xyz"
    },
    "v1n_before_mps": pl.Float64,
    "v2n_before_mps": pl.Float64,
    "v1n_after_mps": pl.Float64,
    "v2n_after_mps": pl.Float64,
    **{f"p{c}_{w}_Ns": pl.Float64 for w in ("before", "after") for c in "xyz"},
    "momentum_rel_change": pl.Float64,
    "ke_before_J": pl.Float64,
    "ke_after_J": pl.Float64,
    "ke_loss_J": pl.Float64,
    "ke_loss_frac": pl.Float64,
    "e_measured": pl.Float64,
    "ke_loss_predicted_J": pl.Float64,
    "v1n_after_e_mps": pl.Float64,
    "v2n_after_e_mps": pl.Float64,
    "v1n_after_elastic_mps": pl.Float64,
    "v2n_after_elastic_mps": pl.Float64,
    "v_after_inelastic_mps": pl.Float64,
    "peak_force_N": pl.Float64,
    "impulse_Ns": pl.Float64,
    "max_penetration_m": pl.Float64,
    "complete": pl.Boolean,
    "note": pl.String,
}


def _vec(prefix: str, suffix: str) -> list[pl.Expr]:
    return [pl.col(f"{prefix}{c}{suffix}") for c in "xyz"]


def _dot(a: list[pl.Expr], b: list[pl.Expr]) -> pl.Expr:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _norm(a: list[pl.Expr]) -> pl.Expr:
    return _dot(a, a).sqrt()


def pair_states(states: pl.DataFrame, times: pl.DataFrame, on: str, tag: str) -> pl.DataFrame:
    """Attach body1's and body2's states at time `on` as columns `<col>1<tag>`, `<col>2<tag>`."""
    for k in ("1", "2"):
        times = state_at(
            states,
            times.with_columns(pl.col(f"body{k}").alias("body")),
            on=on,
            suffix=f"{k}{tag}",
        ).drop("body")
    return times


def collisions(
    intervals: pl.DataFrame, states: pl.DataFrame, infos: dict[str, BodyInfo], *, step_ns: int
) -> pl.DataFrame:
    """One row per contact interval between two free bodies (see the module docstring).

    Args:
        intervals: `contact_intervals` of the run.
        states: `states_long` of the run.
        infos: the run's bodies (masses in kg).
        step_ns: logged step, ns.

    Returns:
        Columns of `COLLISION_SCHEMA`; an interval still open at the end of the log is marked
        incomplete and gets no "after" values.
    """
    names = list(infos)
    hits = (
        intervals.filter(pl.col("body1").is_in(names) & pl.col("body2").is_in(names))
        .sort("start_t_ns")
        .with_columns(
            (pl.int_range(pl.len()).over("body1", "body2") + 1).alias("collision"),
            (pl.col("start_t_ns") - step_ns).alias("before_t_ns"),
            (pl.col("end_t_ns") + step_ns).alias("after_t_ns"),
            pl.col("body1").replace_strict({n: i.mass for n, i in infos.items()}).alias("m1_kg"),
            pl.col("body2").replace_strict({n: i.mass for n, i in infos.items()}).alias("m2_kg"),
        )
        .drop("nx", "ny", "nz")
    )
    if hits.is_empty():
        return pl.DataFrame(schema=COLLISION_SCHEMA)
    hits = pair_states(states, hits, "start_t_ns", "_c")
    hits = pair_states(states, hits, "before_t_ns", "_before")
    hits = pair_states(states, hits, "after_t_ns", "_after")
    d = [pl.col(f"{c}2_c") - pl.col(f"{c}1_c") for c in "xyz"]
    hits = hits.with_columns(*[(d[i] / _norm(d)).alias(f"n{c}") for i, c in enumerate("xyz")])
    return from_pair_states(hits)


def from_pair_states(hits: pl.DataFrame) -> pl.DataFrame:
    """The collision quantities from a frame with masses, normal, and both bodies' states.

    Needs m1_kg, m2_kg, nx, ny, nz, and x1_before .. vz2_after (see `pair_states`).
    """
    n = _vec("n", "")
    m1, m2 = pl.col("m1_kg"), pl.col("m2_kg")
    complete = (
        ~pl.col("open") & pl.col("vx1_after").is_not_null() & pl.col("vx1_before").is_not_null()
    )
    out = hits.with_columns(
        *[
            pl.col(f"v{c}{k}_{w}").alias(f"v{k}{c}_{w}_mps")
            for w in ("before", "after")
            for k in "12"
            for c in "xyz"
        ],
        *[
            (m1 * pl.col(f"v{c}1_{w}") + m2 * pl.col(f"v{c}2_{w}")).alias(f"p{c}_{w}_Ns")
            for w in ("before", "after")
            for c in "xyz"
        ],
        *[
            _dot(_vec("v", f"{k}_{w}"), n).alias(f"v{k}n_{w}_mps")
            for w in ("before", "after")
            for k in "12"
        ],
        *[
            (
                0.5 * m1 * _dot(_vec("v", f"1_{w}"), _vec("v", f"1_{w}"))
                + 0.5 * m2 * _dot(_vec("v", f"2_{w}"), _vec("v", f"2_{w}"))
            ).alias(f"ke_{w}_J")
            for w in ("before", "after")
        ],
    )
    dp = [pl.col(f"p{c}_after_Ns") - pl.col(f"p{c}_before_Ns") for c in "xyz"]
    scale = m1 * _norm(_vec("v", "1_before")) + m2 * _norm(_vec("v", "2_before"))
    v1, v2 = pl.col("v1n_before_mps"), pl.col("v2n_before_mps")
    e = -(pl.col("v2n_after_mps") - pl.col("v1n_after_mps")) / (v2 - v1)
    out = out.with_columns(
        (_norm(dp) / scale).alias("momentum_rel_change"),
        (pl.col("ke_before_J") - pl.col("ke_after_J")).alias("ke_loss_J"),
        e.alias("e_measured"),
    ).with_columns(
        (pl.col("ke_loss_J") / pl.col("ke_before_J")).alias("ke_loss_frac"),
        ((1 - pl.col("e_measured") ** 2) * m1 * m2 * (v1 - v2) ** 2 / (2 * (m1 + m2))).alias(
            "ke_loss_predicted_J"
        ),
    )
    v1e, v2e = collision_after(m1, m2, v1, v2, pl.col("e_measured"))
    v1el, v2el = collision_after(m1, m2, v1, v2, 1.0)
    vin, _ = collision_after(m1, m2, v1, v2, 0.0)
    after_cols = [
        c
        for c in COLLISION_SCHEMA
        if "after" in c or c.startswith("ke_loss") or c in ("e_measured", "momentum_rel_change")
    ]
    out = out.with_columns(
        v1e.alias("v1n_after_e_mps"),
        v2e.alias("v2n_after_e_mps"),
        v1el.alias("v1n_after_elastic_mps"),
        v2el.alias("v2n_after_elastic_mps"),
        vin.alias("v_after_inelastic_mps"),
        (pl.col("start_t_ns") / 1e9).alias("impact_t_s"),
        pl.when(~pl.col("open")).then(pl.col("after_t_ns") / 1e9).alias("release_t_s"),
        complete.alias("complete"),
        pl.when(pl.col("open"))
        .then(pl.lit("contact still open at the end of the log"))
        .otherwise(pl.lit(""))
        .alias("note"),
    )
    keep_after = [
        c
        for c in after_cols
        if c not in ("v1n_after_elastic_mps", "v2n_after_elastic_mps", "v_after_inelastic_mps")
    ]
    out = out.with_columns(
        *[pl.when(pl.col("complete")).then(pl.col(c)).alias(c) for c in keep_after]
    )
    return out.select(list(COLLISION_SCHEMA)).cast(COLLISION_SCHEMA).sort("impact_t_s")


def no_collision_rows(
    run_id: str, states: pl.DataFrame, infos: dict[str, BodyInfo], reason: str
) -> pl.DataFrame:
    """Rows for a run whose bodies never touch: first and last logged state, e unknown.

    The normal is the line of centres at the first logged step; "after" is the last logged
    state, which shows that nothing happened (the handout's Step 3 as written).
    """
    names = [n for n in infos if n in set(states["body"].unique().to_list())]
    if len(names) < 2:
        return pl.DataFrame(schema=COLLISION_SCHEMA)
    first, last = int(states["t_ns"].min()), int(states["t_ns"].max())
    rows = []
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            rows.append(
                {
                    "run_id": run_id,
                    "body1": a,
                    "body2": b,
                    "m1_kg": infos[a].mass,
                    "m2_kg": infos[b].mass,
                }
            )
    hits = pl.DataFrame(rows).with_columns(
        pl.lit(None, dtype=pl.Int64).alias("collision"),
        pl.lit(first).alias("start_t_ns"),
        pl.lit(first).alias("before_t_ns"),
        pl.lit(last).alias("after_t_ns"),
        pl.lit(None, dtype=pl.Float64).alias("duration_s"),
        pl.lit(None, dtype=pl.Float64).alias("peak_force_N"),
        pl.lit(None, dtype=pl.Float64).alias("impulse_Ns"),
        pl.lit(None, dtype=pl.Float64).alias("max_penetration_m"),
        pl.lit(False).alias("open"),
    )
    hits = pair_states(states, hits, "before_t_ns", "_c")
    hits = pair_states(states, hits, "before_t_ns", "_before")
    hits = pair_states(states, hits, "after_t_ns", "_after")
    d = [pl.col(f"{c}2_c") - pl.col(f"{c}1_c") for c in "xyz"]
    hits = hits.with_columns(*[(d[i] / _norm(d)).alias(f"n{c}") for i, c in enumerate("xyz")])
    out = from_pair_states(hits)
    return out.with_columns(
        pl.lit(None, dtype=pl.Float64).alias("e_measured"),
        pl.lit(None, dtype=pl.Float64).alias("ke_loss_predicted_J"),
        pl.lit(None, dtype=pl.Float64).alias("v1n_after_e_mps"),
        pl.lit(None, dtype=pl.Float64).alias("v2n_after_e_mps"),
        pl.lit(None, dtype=pl.Float64).alias("impact_t_s"),
        pl.lit(None, dtype=pl.Float64).alias("release_t_s"),
        pl.lit(False).alias("complete"),
        pl.lit(reason).alias("note"),
    )
