"""Body-body collisions: momentum and kinetic energy before and after, e, and the 1D outcome."""

from __future__ import annotations

import itertools

import polars as pl

from impactlab.analyze.measure.episodes import e_energy, e_velocity
from impactlab.analyze.measure.states import state_at
from impactlab.logs.load import BodyInfo
from impactlab.physics import collision_after

CENTRAL_LEVER = 1e-6
"""An impact is central when the normal passes each centre of mass within this fraction of
the contact point's distance from it."""

COLLISION_SCHEMA = pl.Schema(
    {
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
        "e_velocity": pl.Float64,
        "e_energy": pl.Float64,
        "target_e": pl.Float64,
        "ke_loss_predicted_J": pl.Float64,
        "v1n_after_e_mps": pl.Float64,
        "v2n_after_e_mps": pl.Float64,
        "v1n_after_elastic_mps": pl.Float64,
        "v2n_after_elastic_mps": pl.Float64,
        "v_after_inelastic_mps": pl.Float64,
        "peak_force_N": pl.Float64,
        "impulse_Ns": pl.Float64,
        "max_penetration_m": pl.Float64,
        "touched_by": pl.String,
        "gravity_impulse_rel": pl.Float64,
        "complete": pl.Boolean,
        "note": pl.String,
    }
)


def _vec(prefix: str, suffix: str) -> list[pl.Expr]:
    return [pl.col(f"{prefix}{c}{suffix}") for c in "xyz"]


def _dot(a: list[pl.Expr], b: list[pl.Expr]) -> pl.Expr:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _norm(a: list[pl.Expr]) -> pl.Expr:
    return _dot(a, a).sqrt()


def collisions(episodes: pl.DataFrame, infos: dict[str, BodyInfo]) -> pl.DataFrame:
    """One row per contact episode of two rigid bodies of a run (see docs/analysis.md).

    "Before" is both bodies' state at the first step in contact, "after" at the first step
    after it (the recorder's, at every step: independent of the logging stride); n is the
    contact normal then (from body1 to body2); v1n, v2n are the velocities of each body's
    contact point along n (v + w x r).

    Args:
        episodes: the run's episodes of kind "body" (`episodes.episodes`).
        infos: the run's bodies (masses in kg).

    Returns:
        Columns of `COLLISION_SCHEMA`; a contact still open at the end of the run is
        incomplete and gets no "after" values.
    """
    names = list(infos)
    hits = episodes.filter(pl.col("body").is_in(names) & pl.col("other").is_in(names))
    if hits.is_empty():
        return pl.DataFrame(schema=COLLISION_SCHEMA)
    mass = {n: i.mass for n, i in infos.items()}
    states = {
        f"{f}{k}_{w}": pl.col(f"s{k}_{tag}_{f}")
        for k in "12"
        for w, tag in (("before", "in"), ("after", "out"))
        for f in ("x", "y", "z", "vx", "vy", "vz", "wx", "wy", "wz")
    }
    n = [pl.col(f"n{c}_in") for c in "xyz"]

    def normal_speed(k: str, w: str, point: str) -> pl.Expr:
        r = [pl.col(f"p{c}_{point}") - states[f"{c}{k}_{w}"] for c in "xyz"]
        v = [states[f"v{c}{k}_{w}"] for c in "xyz"]
        wv = [states[f"w{c}{k}_{w}"] for c in "xyz"]
        return _dot(n, [v[i] + _cross(wv, r)[i] for i in range(3)])

    def lever(k: str) -> pl.Expr:
        r = [pl.col(f"p{c}_in") - states[f"{c}{k}_before"] for c in "xyz"]
        return _norm(_cross(r, n)) / _norm(r)

    hits = (
        hits.sort("start_t_ns")
        .rename({"body": "body1", "other": "body2"})
        .with_columns(
            (pl.int_range(pl.len()).over("body1", "body2") + 1).alias("collision"),
            pl.col("body1").replace_strict(mass).alias("m1_kg"),
            pl.col("body2").replace_strict(mass).alias("m2_kg"),
            *[pl.col(f"n{c}_in").alias(f"n{c}") for c in "xyz"],
            *[e.alias(k) for k, e in states.items()],
            normal_speed("1", "before", "in").alias("v1n_before_mps"),
            normal_speed("2", "before", "in").alias("v2n_before_mps"),
            normal_speed("1", "after", "out").alias("v1n_after_mps"),
            normal_speed("2", "after", "out").alias("v2n_after_mps"),
            (pl.max_horizontal(lever("1"), lever("2")) <= CENTRAL_LEVER).alias("central"),
            (pl.col("release_t_s") - pl.col("impact_t_s")).alias("duration_s"),
        )
    )
    return from_pair_states(hits)


def _cross(a: list[pl.Expr], b: list[pl.Expr]) -> list[pl.Expr]:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def from_pair_states(hits: pl.DataFrame) -> pl.DataFrame:
    """The collision quantities from a frame with masses, normal, normal velocities of the
    contact points and both bodies' states (see `pair_states`).

    Needs m1_kg, m2_kg, nx, ny, nz, v1n/v2n_before/after_mps, central, open, and x1_before ..
    vz2_after.
    """
    m1, m2 = pl.col("m1_kg"), pl.col("m2_kg")
    complete = (
        ~pl.col("open")
        & ~pl.col("initial")
        & pl.col("vx1_after").is_not_null()
        & pl.col("vx1_before").is_not_null()
        & (pl.col("v2n_before_mps") < pl.col("v1n_before_mps"))  # closing
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
    out = out.with_columns(
        (_norm(dp) / scale).alias("momentum_rel_change"),
        (pl.col("ke_before_J") - pl.col("ke_after_J")).alias("ke_loss_J"),
        e_velocity().alias("e_velocity"),
        e_energy().alias("e_energy"),
    ).with_columns(
        (pl.col("ke_loss_J") / pl.col("ke_before_J")).alias("ke_loss_frac"),
        ((1 - pl.col("e_velocity") ** 2) * m1 * m2 * (v1 - v2) ** 2 / (2 * (m1 + m2))).alias(
            "ke_loss_predicted_J"
        ),
    )
    v1e, v2e = collision_after(m1, m2, v1, v2, pl.col("e_velocity"))
    v1el, v2el = collision_after(m1, m2, v1, v2, 1.0)
    vin, _ = collision_after(m1, m2, v1, v2, 0.0)
    central = pl.col("central")
    out = out.with_columns(
        pl.when(central).then(v1e).alias("v1n_after_e_mps"),
        pl.when(central).then(v2e).alias("v2n_after_e_mps"),
        pl.when(central).then(v1el).alias("v1n_after_elastic_mps"),
        pl.when(central).then(v2el).alias("v2n_after_elastic_mps"),
        pl.when(central).then(vin).alias("v_after_inelastic_mps"),
        pl.when(central).then(pl.col("ke_loss_predicted_J")).alias("ke_loss_predicted_J"),
        pl.when(~pl.col("open")).then(pl.col("release_t_s")).alias("release_t_s"),
        complete.alias("complete"),
        pl.when(pl.col("initial"))
        .then(pl.lit("the bodies touch from the start: no impact, no 'before'"))
        .when(pl.col("open"))
        .then(pl.lit("contact still open at the end of the run"))
        .when(pl.col("e_note") != "")
        .then(pl.col("e_note"))
        .when(~central)
        .then(pl.lit("eccentric impact: the 1D formulas for the outcome do not apply"))
        .otherwise(pl.lit(""))
        .alias("note"),
    )
    out = out.with_columns(
        *[
            pl.lit(None, dtype=COLLISION_SCHEMA[c]).alias(c)
            for c in ("touched_by", "gravity_impulse_rel", "target_e")
            if c not in out.columns
        ]
    )
    after_cols = [
        c
        for c in COLLISION_SCHEMA
        if ("after" in c and c not in ELASTIC_COLUMNS)
        or c.startswith("ke_loss")
        or c in ("e_velocity", "momentum_rel_change")
    ]
    before_cols = [  # a pair touching from the start has no state before an impact
        c for c in COLLISION_SCHEMA if "before" in c or c in ELASTIC_COLUMNS
    ]
    out = out.with_columns(
        *[pl.when(pl.col("complete")).then(pl.col(c)).alias(c) for c in after_cols]
    ).with_columns(*[pl.when(~pl.col("initial")).then(pl.col(c)).alias(c) for c in before_cols])
    return out.select(list(COLLISION_SCHEMA)).cast(COLLISION_SCHEMA).sort("impact_t_s")


def with_surroundings(
    col: pl.DataFrame, episodes: pl.DataFrame, gravity: float, articulated: frozenset[str]
) -> pl.DataFrame:
    """The collisions with what else acted on each pair during it: `touched_by`, the other
    bodies and surfaces in contact with either body then, and "<body>'s joints" for an
    `articulated` body of the pair ("" none), and `gravity_impulse_rel`, (m1 + m2) |g| T
    over the contact's duration T / (|m1 v1| + |m2 v2|).

    Args:
        col: the run's collisions (`collisions`); episodes: all its episodes.
        gravity: |g|, m/s^2.
    """
    if col.is_empty():
        return col
    spans = episodes.select("body", "other", "start_t_ns", "end_t_ns").rows()
    touched: list[str | None] = []
    for a, b, t0, t1 in zip(
        *(col[c].to_list() for c in ("body1", "body2", "impact_t_s", "release_t_s")), strict=True
    ):
        if t0 is None or t1 is None:
            touched.append(None)
            continue
        lo, hi = round(t0 * 1e9), round(t1 * 1e9)
        names = {f"{x}'s joints" for x in (a, b) if x in articulated}
        for x, y, s, e in spans:
            if e > lo and s < hi and {x, y} != {a, b} and ({x, y} & {a, b}):
                names.update({x, y} - {a, b})
        touched.append(", ".join(sorted(names)))
    m1, m2 = pl.col("m1_kg"), pl.col("m2_kg")
    p = m1 * _norm(_vec("v1", "_before_mps")) + m2 * _norm(_vec("v2", "_before_mps"))
    return col.with_columns(
        pl.Series("touched_by", touched, dtype=pl.String),
        ((m1 + m2) * gravity * pl.col("duration_s") / p)
        .fill_nan(None)
        .alias("gravity_impulse_rel"),
    )


NO_EPISODE = ("v_in_mps", "v_out_mps", "work_c_J", "work_r_J", "impact_t_s", "release_t_s")
ELASTIC_COLUMNS = ("v1n_after_elastic_mps", "v2n_after_elastic_mps", "v_after_inelastic_mps")


def no_collision_rows(
    run_id: str, states: pl.DataFrame, infos: dict[str, BodyInfo], reason: str
) -> pl.DataFrame:
    """Rows for a run whose bodies never touch: first and last logged state, e unknown.

    The normal is the line of centres at the first logged row; "after" is the last logged
    state, which shows that nothing happened (the handout's Step 3 as written). The elastic
    and inelastic answers are given for two spheres (whose impact would be central).
    """
    names = [n for n in infos if n in set(states["body"].unique().to_list())]
    if len(names) < 2:
        return pl.DataFrame(schema=COLLISION_SCHEMA)
    row = states["row"].to_numpy()
    first, last = int(row.min()), int(row.max())
    rows = [
        {
            "run_id": run_id,
            "body1": a,
            "body2": b,
            "m1_kg": infos[a].mass,
            "m2_kg": infos[b].mass,
            "central": infos[a].radius is not None and infos[b].radius is not None,
        }
        for i, a in enumerate(names)
        for b in names[i + 1 :]
    ]
    hits = pl.DataFrame(rows).with_columns(
        pl.lit(None, dtype=pl.Int64).alias("collision"),
        pl.lit(first).alias("row_b"),
        pl.lit(last).alias("row_a"),
        pl.lit(None, dtype=pl.Float64).alias("duration_s"),
        pl.lit(None, dtype=pl.Float64).alias("peak_force_N"),
        pl.lit(None, dtype=pl.Float64).alias("impulse_Ns"),
        pl.lit(None, dtype=pl.Float64).alias("max_penetration_m"),
        pl.lit(False).alias("open"),
        pl.lit(False).alias("initial"),
        pl.lit("").alias("e_note"),
        *[pl.lit(None, dtype=pl.Float64).alias(c) for c in NO_EPISODE],
    )
    for k, (at, tag) in itertools.product("12", (("row_b", "_before"), ("row_a", "_after"))):
        hits = state_at(states, hits, body=f"body{k}", row=at, suffix=f"{k}{tag}")
    d = [pl.col(f"{c}2_before") - pl.col(f"{c}1_before") for c in "xyz"]
    n = [d[i] / _norm(d) for i in range(3)]
    hits = hits.with_columns(
        *[n[i].alias(f"n{c}") for i, c in enumerate("xyz")],
        *[
            _dot(n, _vec("v", f"{k}_{w}")).alias(f"v{k}n_{w}_mps")
            for k in "12"
            for w in ("before", "after")
        ],
    )
    # no episode: e, its predictions and the times are null already
    return from_pair_states(hits).with_columns(
        pl.lit(False).alias("complete"), pl.lit(reason).alias("note")
    )
