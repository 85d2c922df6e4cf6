"""Energy of each body and of the run: kinetic (translational, rotational), potential, total.

Potential energy is measured from a reference height per body (`impactlab.analyze.ground`):
with a ground, the level of the surface the body lands on first plus the body's rest height
(a ball resting on a plane has zero potential energy; a box resting on its largest face
too); without one, the body's initial position. MuJoCo's own potential energy is m g z of
the centre (relative to the world origin) of every body, static ones included (the log's
`static_potential_J`), so `mujoco_total_J` is shifted by that and sum(-m g . r_ref) before it
is compared. `height_m` is the body's clearance above its
reference surface (its lowest point), or, without a clearance, its centre's height above
the reference.

Flight phases are the runs of logged rows in no contact (contacts merged across chatter);
the energy of the run should stay constant there (`drift_J`). Each contact phase loses
`loss_J`: the energy at the last logged row before it minus that at the first logged row
after it, so that E(start) - E(end) = sum(loss_J) - sum(drift_J) exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from impactlab.analyze.ground import Ground
from impactlab.logs.load import BodyInfo, RunLog

ENERGY_COLUMNS = ("ke_trans_J", "ke_rot_J", "pe_J", "total_J")


@dataclass(frozen=True)
class Reference:
    """Where a body's potential energy is zero: a point (only its height along -gravity
    matters), and the surface its heights are measured from (None: centre above `point`)."""

    point: np.ndarray
    surface: str | None


def references(
    run: RunLog, ground: Ground, states: pl.DataFrame, first_surface: dict[str, str]
) -> dict[str, Reference]:
    """Per body, its energy reference (see the module docstring).

    Args:
        first_surface: per body, the surface of its first ground contact (if any).
    """
    refs = {}
    for name, info in run.body_info.items():
        surface = ground.reference(name, first_surface.get(name), info.rest_height_m)
        if surface is not None and info.rest_height_m is not None:
            level = ground.surfaces[surface].level_m + info.rest_height_m
            measured = ground.has_clearance(name, surface)
            refs[name] = Reference(level * ground.up, surface if measured else None)
            continue
        mine = states.filter(pl.col("body") == name)
        start = mine.select("x", "y", "z").row(0) if mine.height else (0.0, 0.0, 0.0)
        refs[name] = Reference(np.asarray(start, dtype=float), None)
    return refs


def body_frame_omega() -> list[pl.Expr]:
    """Angular velocity in the body frame (wbx, wby, wbz), rad/s: q* (wx, wy, wz) q.

    The quaternion (qw, qx, qy, qz) rotates body to world, so the world-frame vector is rotated
    by its conjugate u = -(qx, qy, qz): t = 2 u x w, w_b = w + qw t + u x t.
    """
    ux, uy, uz = -pl.col("qx"), -pl.col("qy"), -pl.col("qz")
    wx, wy, wz = pl.col("wx"), pl.col("wy"), pl.col("wz")
    tx, ty, tz = 2 * (uy * wz - uz * wy), 2 * (uz * wx - ux * wz), 2 * (ux * wy - uy * wx)
    return [
        (wx + pl.col("qw") * tx + (uy * tz - uz * ty)).alias("wbx"),
        (wy + pl.col("qw") * ty + (uz * tx - ux * tz)).alias("wby"),
        (wz + pl.col("qw") * tz + (ux * ty - uy * tx)).alias("wbz"),
    ]


def body_energy(
    states: pl.DataFrame, info: BodyInfo, *, gravity: np.ndarray, ref: np.ndarray
) -> pl.DataFrame:
    """Energy of one body at each logged step.

    Args:
        states: the body's states (run_id, t_ns, t_s, x .. wz), world frame.
        info: mass (kg) and principal inertia (kg m^2, body frame).
        gravity: (3,) m/s^2.
        ref: (3,) position of zero potential energy, m.

    Returns:
        (run_id, body, t_ns, t_s, height_m, ke_trans_J, ke_rot_J, pe_J, total_J); height_m is
        the centre's height above `ref` along -gravity.
    """
    m = info.mass
    ix, iy, iz = info.inertia
    g = float(np.linalg.norm(gravity))
    up = -gravity / g if g > 0 else np.array([0.0, 0.0, 1.0])
    # Python floats: a numpy scalar times an expression would run as a slow ufunc callback
    ux, uy, uz = (float(u) for u in up)
    gx, gy, gz = (float(c) for c in gravity)
    dx, dy, dz = pl.col("x") - ref[0], pl.col("y") - ref[1], pl.col("z") - ref[2]
    return (
        states.with_columns(body_frame_omega())
        .select(
            "run_id",
            pl.lit(info.name).alias("body"),
            "t_ns",
            "t_s",
            (ux * dx + uy * dy + uz * dz).alias("height_m"),
            (0.5 * m * (pl.col("vx") ** 2 + pl.col("vy") ** 2 + pl.col("vz") ** 2)).alias(
                "ke_trans_J"
            ),
            (
                0.5 * (ix * pl.col("wbx") ** 2 + iy * pl.col("wby") ** 2 + iz * pl.col("wbz") ** 2)
            ).alias("ke_rot_J"),
            (-m * (gx * dx + gy * dy + gz * dz)).alias("pe_J"),
        )
        .with_columns((pl.col("ke_trans_J") + pl.col("ke_rot_J") + pl.col("pe_J")).alias("total_J"))
    )


def run_energy(
    run: RunLog, states: pl.DataFrame, ground: Ground, refs: dict[str, Reference]
) -> pl.DataFrame:
    """Energy per body and for the whole run (body = "total"), with MuJoCo's total compared.

    Args:
        states: `states_long` of the run.
        refs: `references` of the run.

    Returns:
        (run_id, body, t_ns, t_s, height_m, ke_trans_J, ke_rot_J, pe_J, total_J,
        mujoco_total_J, mujoco_diff_J), by body and time; the MuJoCo columns are set on the
        "total" rows only: MuJoCo's total minus sum(-m g . r_ref), and that minus total_J.
    """
    infos = run.body_info
    by_body = {str(k[0]): f for k, f in states.partition_by("body", as_dict=True).items()}
    per_body = {}
    for name, ref in refs.items():
        if name not in run.bodies:
            continue
        mine = by_body.get(name, states.clear())
        frame = body_energy(mine, infos[name], gravity=run.gravity, ref=ref.point)
        if ref.surface is not None:  # heights: the lowest point above the reference surface
            c, found = ground.clearance_at(name, ref.surface, frame["t_ns"].to_numpy())
            frame = frame.with_columns(with_nulls("height_m", c, found))
        per_body[name] = frame.select(ENERGY_FRAME_COLUMNS)
    if not per_body:
        return empty_energy()
    shift = float(sum(-infos[n].mass * run.gravity @ refs[n].point for n in refs))
    shift += run.static_potential_J  # MuJoCo counts the static bodies' mass too
    total = total_energy(list(per_body.values()), run.energy, shift)
    frames = per_body | {"total": total}
    if len(frames) == len(per_body):  # a body named "total": order by time as well
        return pl.concat(list(frames.values()), how="diagonal").sort("body", "t_ns")
    # each frame is by time (states_long is): ordering the bodies by name sorts by (body, t_ns)
    return pl.concat([frames[n] for n in sorted(frames)], how="diagonal")


def with_nulls(name: str, values: np.ndarray, found: np.ndarray) -> pl.Series:
    """`values` as a Float64 column, null where not `found`."""
    column = pl.Series(name, values, dtype=pl.Float64)
    return column.scatter(np.flatnonzero(~found), None) if not found.all() else column


def total_energy(bodies: list[pl.DataFrame], mujoco: pl.DataFrame, shift: float) -> pl.DataFrame:
    """The run's "total" rows: the bodies' energies summed at each logged time, and MuJoCo's
    total (`mujoco`: t_ns, total) minus `shift` where it was logged at that time.

    When every body is logged at the same times (always, except in a damaged log), the sums
    are taken over the arrays in the bodies' order, as a group-by sums them.
    """
    first = bodies[0]
    same = all(
        f.height == first.height
        and f["t_ns"].equals(first["t_ns"])
        and f["t_s"].equals(first["t_s"])
        and f["run_id"].equals(first["run_id"])
        and not any(f[c].null_count() for c in ENERGY_COLUMNS)
        for f in bodies
    )
    if not same:
        total = (
            pl.concat(bodies)
            .group_by("run_id", "t_ns", "t_s", maintain_order=True)
            .agg(*[pl.col(c).sum() for c in ENERGY_COLUMNS])
        )
    else:
        sums = {c: first[c].to_numpy() for c in ENERGY_COLUMNS}
        for f in bodies[1:]:
            sums = {c: sums[c] + f[c].to_numpy() for c in ENERGY_COLUMNS}
        total = pl.DataFrame(
            [first["run_id"], first["t_ns"], first["t_s"]]
            + [pl.Series(c, v, dtype=pl.Float64) for c, v in sums.items()]
        )
    t = total["t_ns"].to_numpy()
    logged, values = mujoco["t_ns"].to_numpy(), mujoco["total"].to_numpy()
    order = np.argsort(logged, kind="stable")
    logged, values = logged[order], values[order]
    found = np.zeros(t.size, dtype=bool)
    theirs = np.full(t.size, np.nan)
    if logged.size:
        spot = np.clip(np.searchsorted(logged, t), 0, logged.size - 1)
        found = (logged[spot] == t) & mujoco["total"].is_not_null().to_numpy()[order][spot]
        theirs[found] = values[spot[found]] - shift
    mujoco_total = with_nulls("mujoco_total_J", theirs, found)
    return total.select(
        "run_id",
        pl.lit("total").alias("body"),
        "t_ns",
        "t_s",
        pl.lit(None, dtype=pl.Float64).alias("height_m"),
        *ENERGY_COLUMNS,
        mujoco_total,
        (mujoco_total - total["total_J"]).alias("mujoco_diff_J"),
    )


ENERGY_FRAME_COLUMNS = ("run_id", "body", "t_ns", "t_s", "height_m", *ENERGY_COLUMNS)


def empty_energy() -> pl.DataFrame:
    """An energy frame with no rows."""
    schema = {"run_id": pl.String, "body": pl.String, "t_ns": pl.Int64, "t_s": pl.Float64}
    schema |= {c: pl.Float64 for c in ("height_m", *ENERGY_COLUMNS)}
    schema |= {c: pl.Float64 for c in ("mujoco_total_J", "mujoco_diff_J")}
    return pl.DataFrame(schema=schema)


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
        total.select("run_id", "t_ns", "t_s", "total_J")
        .with_columns(in_contact.alias("in_contact"))
        .with_columns(pl.col("in_contact").rle_id().over("run_id").alias("phase"))
        .group_by("run_id", "phase", maintain_order=True)
        .agg(
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
