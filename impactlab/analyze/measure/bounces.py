"""Bounces of each body on each ground surface, from the contact point (not from thresholds on
the centre's velocity).

A bounce is a contact of a body with a surface that is an impact (the body arrives faster
than v_min, see `impactlab.analyze.measure.impacts`) or is followed by a visible flight; contacts at
rest, sliding or rolling, chatter included, are one resting contact and no bounce. Bounce n
(1-based) counts per body and surface. v_in < 0 and v_out > 0 are the normal velocities of
the contact point at the moments the surfaces meet and part (ballistic extrapolation across
logging gaps), e_velocity = -v_out / v_in. Heights are the body's clearance above the surface
(its lowest point): apex_before_m is the apex of the flight that ends in this bounce,
apex_m that of the flight after it (`impactlab.analyze.measure.flights`), e_apex = sqrt(apex_m /
apex_before_m), apex_predicted_m = v_out^2 / (2 g_n) with g_n gravity along the normal.
Quantities a bounce does not define are left empty and the `note` says why.

An articulated body (a link of a jointed or welded tree) does not fly on a parabola: its
joints and the rest of its tree push it between contacts. Its apex quantities are left
empty; v_in and v_out are still the contact point's normal velocities from both bodies'
logged motion, extrapolated across a logging gap with gravity alone (exact when every step
is logged; the joints' push over the gap is the error otherwise). An e_velocity above 1 is
kept as measured and its note says why it is not a restitution (`E_ABOVE_ONE`).

e_energy is the energetic coefficient (Stronge): sqrt(W_r / -W_c), the work of the normal
contact force on the contact points' relative normal motion while they separate over that
while they approach, summed over the contact's every simulated step by the recorder (the
log's `/contact_work/...`, `impactlab.record.contact_work`), so the logging stride does not
change it. It is at most 1 for a contact that dissipates, for turning, rough and articulated
bodies alike; under gravity it is slightly below e_velocity (gravity works on the body
during the contact, and W counts the contact force alone). `e_basis` names the one a reader
should use: "velocity" for a ballistic body that does not turn and leaves no faster than it
came (both agree then, and e_velocity is what the handout defines), "energy" otherwise.
"""

from __future__ import annotations

import polars as pl

BOUNCE_SCHEMA = pl.Schema(
    {
        "run_id": pl.String,
        "body": pl.String,
        "surface": pl.String,
        "bounce": pl.Int64,
        "impact_t_s": pl.Float64,
        "release_t_s": pl.Float64,
        "duration_s": pl.Float64,
        "v_in_mps": pl.Float64,
        "v_out_mps": pl.Float64,
        "e_velocity": pl.Float64,
        "e_energy": pl.Float64,
        "e_basis": pl.String,
        "apex_before_m": pl.Float64,
        "apex_m": pl.Float64,
        "apex_predicted_m": pl.Float64,
        "e_apex": pl.Float64,
        "peak_force_N": pl.Float64,
        "impulse_Ns": pl.Float64,
        "max_penetration_m": pl.Float64,
        "n_raw_contacts": pl.Int64,
        "complete": pl.Boolean,
        "note": pl.String,
    }
)
TURNING = (
    "the body turns in flight (its lowest point moves relative to its centre of mass), so "
    "apex heights do not measure e"
)


ARTICULATED = (
    "an articulated body (moved by its joints and tree between contacts, not ballistic): no "
    "apex heights; v_in and v_out are extrapolated across logging gaps with gravity alone"
)
E_ABOVE_ONE = (
    "e_velocity > 1: the contact point leaves faster than it arrived, fed by the body's "
    "rotation or its joints; a velocity ratio, not a restitution (no contact returns more "
    "energy than it takes)"
)


def is_bounce() -> pl.Expr:
    """A merged ground contact that is an impact or is followed by a visible flight."""
    impact = pl.col("row_b").is_not_null() & (pl.col("v_in_mps") < -pl.col("v_min_mps"))
    return impact | pl.col("visible")


def bounces(
    contacts: pl.DataFrame,
    flights: pl.DataFrame,
    *,
    gravity_n: pl.Expr,
    articulated: list[tuple[str, str]] | None = None,
    work: pl.DataFrame | None = None,
) -> pl.DataFrame:
    """One row per bounce (see the module docstring).

    Args:
        articulated: (run_id, body) of the bodies that are not ballistic.
        work: the runs' `RunLog.contact_work` (none: e_energy is empty).
        contacts: the merged ground contacts (`merge_chatter` of kind "ground"), with the
            per-body contact index `contact` (0-based, over every surface).
        flights: `impactlab.analyze.measure.flights.flights` of the run.
        gravity_n: gravity along the release normal towards the surface (m/s^2), an
            expression over `contacts`.

    Returns:
        Columns of `BOUNCE_SCHEMA`, sorted by body, surface and bounce; no rows without any.
    """
    if contacts.is_empty():
        return pl.DataFrame(schema=BOUNCE_SCHEMA)
    rows = contacts.filter(is_bounce()).sort("run_id", "body", "other", "start_t_ns")
    if rows.is_empty():
        return pl.DataFrame(schema=BOUNCE_SCHEMA)
    before = flights.select(
        "run_id",
        "body",
        pl.col("flight").alias("contact"),
        "apex_before_m",
        pl.col("reached").alias("before_reached"),
        pl.col("turning_before"),
    )
    after = flights.select(
        "run_id",
        "body",
        (pl.col("flight") - 1).alias("contact"),
        "apex_after_m",
        pl.col("reached").alias("after_reached"),
        pl.col("turning_after"),
    )
    rows = (
        rows.join(before, on=["run_id", "body", "contact"], how="left", maintain_order="left")
        .join(after, on=["run_id", "body", "contact"], how="left", maintain_order="left")
        .with_columns(
            (pl.int_range(pl.len()).over("run_id", "body", "other") + 1).alias("bounce"),
            gravity_n.alias("g_n"),
        )
    )
    links = pl.DataFrame(
        articulated or [], schema={"run_id": pl.String, "body": pl.String}, orient="row"
    ).with_columns(pl.lit(True).alias("articulated"))
    rows = rows.join(links, on=["run_id", "body"], how="left", maintain_order="left").with_columns(
        pl.col("articulated").fill_null(False)
    )
    complete = (
        pl.col("row_b").is_not_null()
        & pl.col("visible")
        & (pl.col("v_in_mps") < -pl.col("v_min_mps"))
    )
    rows = _with_work(rows, work)
    ballistic = ~pl.col("articulated")
    apex_after_ok = complete & pl.col("after_reached") & ~pl.col("turning_after") & ballistic
    apex_before_ok = pl.col("before_reached") & ~pl.col("turning_before") & ballistic
    apex_m = pl.when(apex_after_ok).then(pl.col("apex_after_m"))
    apex_before = pl.when(apex_before_ok).then(pl.col("apex_before_m"))
    e_energy = (
        pl.when(~pl.col("work_open") & (pl.col("work_c") < 0) & (pl.col("work_r") >= 0))
        .then((pl.col("work_r") / -pl.col("work_c")).sqrt())
        .otherwise(None)
    )
    duration = pl.when(pl.col("meet_t_s").is_not_null() & pl.col("release_t_s").is_not_null())
    start_s = pl.coalesce("meet_t_s", pl.col("start_t_ns") / 1e9)
    return (
        rows.with_columns(apex_m.alias("apex"), apex_before.alias("apex_b"))
        .select(
            "run_id",
            "body",
            pl.col("other").alias("surface"),
            "bounce",
            start_s.alias("impact_t_s"),
            pl.when(pl.col("visible"))
            .then(pl.coalesce("release_t_s", pl.col("t_a_ns") / 1e9))
            .alias("release_t_s"),
            duration.then(pl.col("release_t_s") - pl.col("meet_t_s"))
            .otherwise((pl.col("end_t_ns") - pl.col("start_t_ns")) / 1e9 + pl.col("interval_s"))
            .alias("duration_s"),
            pl.when(pl.col("row_b").is_not_null()).then(pl.col("v_in_mps")).alias("v_in_mps"),
            pl.when(pl.col("visible")).then(pl.col("v_out_mps")).alias("v_out_mps"),
            pl.when(complete).then(-pl.col("v_out_mps") / pl.col("v_in_mps")).alias("e_velocity"),
            e_energy.alias("e_energy"),
            pl.when(
                complete
                & ballistic
                & ~pl.col("turning_after").fill_null(True)
                & (pl.col("v_out_mps") <= -pl.col("v_in_mps"))
            )
            .then(pl.lit("velocity"))
            .when(e_energy.is_not_null())
            .then(pl.lit("energy"))
            .alias("e_basis"),
            pl.col("apex_b").alias("apex_before_m"),
            pl.col("apex").alias("apex_m"),
            pl.when(
                complete
                & ballistic
                & (pl.col("g_n") > 0)
                & ~pl.col("turning_after").fill_null(True)
            )
            .then(pl.col("v_out_mps") ** 2 / (2 * pl.col("g_n")))
            .alias("apex_predicted_m"),
            pl.when(pl.col("apex").is_not_null() & (pl.col("apex_b") > 0))
            .then((pl.col("apex").clip(0.0) / pl.col("apex_b")).sqrt())
            .alias("e_apex"),
            "peak_force_N",
            "impulse_Ns",
            "max_penetration_m",
            pl.col("n_raw").alias("n_raw_contacts"),
            complete.alias("complete"),
            note().alias("note"),
        )
        .cast(BOUNCE_SCHEMA)
        .sort("run_id", "body", "surface", "bounce")
    )


def _with_work(rows: pl.DataFrame, work: pl.DataFrame | None) -> pl.DataFrame:
    """Each ground contact's work (work_c, work_r, J; work_open): the recorded contacts of
    its body with its surface that start after the last logged row before it and no later
    than its last logged row in contact (chatter merged into one bounce sums its parts)."""
    none = {"work_c": pl.Float64, "work_r": pl.Float64, "work_open": pl.Boolean}
    rows = rows.with_row_index("_row")
    if work is None or work.is_empty():
        return rows.with_columns(pl.lit(None, dtype=t).alias(c) for c, t in none.items())
    on_ground = work.select(
        "run_id",
        pl.col("body2").alias("body"),
        pl.col("geom1").alias("other"),
        "start_ns",
        pl.col("work_compression_J").alias("w_c"),
        pl.col("work_restitution_J").alias("w_r"),
        "open",
    )
    window = rows.select("_row", "run_id", "body", "other", "t_b_ns", "end_t_ns")
    sums = (
        window.join(on_ground, on=["run_id", "body", "other"])
        .filter(
            (pl.col("start_ns") > pl.col("t_b_ns").fill_null(-1))
            & (pl.col("start_ns") <= pl.col("end_t_ns"))
        )
        .group_by("_row")
        .agg(
            pl.col("w_c").sum().alias("work_c"),
            pl.col("w_r").sum().alias("work_r"),
            pl.col("open").any().alias("work_open"),
        )
    )
    return rows.join(sums, on="_row", how="left", maintain_order="left")


def note() -> pl.Expr:
    """Why a bounce lacks a quantity (empty when it has them all)."""
    surface = pl.col("other")
    return (
        pl.when(pl.col("open"))
        .then(
            pl.format(
                "still in contact with {} at the end of the log (at rest, sliding or rolling, "
                "or cut off)",
                surface,
            )
        )
        .when(~pl.col("visible"))
        .then(
            pl.format(
                "no visible flight after it: the body stays on {} (a release slower than "
                "v_min = {} m/s cannot be told from a resting contact)",
                surface,
                pl.col("v_min_mps").round_sig_figs(3),
            )
        )
        .when(pl.col("row_b").is_null())
        .then(pl.lit("in contact at the first logged step"))
        .when(pl.col("v_out_mps") > -pl.col("v_in_mps"))
        .then(pl.lit(E_ABOVE_ONE))
        .when(pl.col("articulated"))
        .then(pl.lit(ARTICULATED))
        .when(pl.col("turning_after").fill_null(False))
        .then(pl.lit(TURNING))
        .when(pl.col("apex_after_m").is_null())
        .then(pl.lit("no clearance to this surface in the log, so no heights"))
        .when(~pl.col("after_reached").fill_null(False))
        .then(pl.lit("the log ends before the apex after this bounce"))
        .otherwise(pl.lit(""))
    )


def no_bounce_rows(reasons: list[tuple[str, str, str]]) -> pl.DataFrame:
    """Rows for bodies without any bounce, from (run_id, body, reason): body and the reason
    only."""
    rows = [
        {k: None for k in BOUNCE_SCHEMA}
        | {"run_id": run_id, "body": body, "complete": False, "note": why}
        for run_id, body, why in reasons
    ]
    return pl.DataFrame(rows, schema=BOUNCE_SCHEMA)
