"""Energy of each body and of the run: kinetic (translational, rotational), potential, total.

Potential energy is measured from a reference height per body (`impactlab.analyze.measure.ground`):
with a ground, the level of the surface the body lands on first plus the body's rest height
(a ball resting on a plane has zero potential energy; a box resting on its largest face
too); without one, the body's initial position. MuJoCo's own potential energy is m g z of
the centre (relative to the world origin) of every body, static ones included (the log's
`static_potential_J`), so `mujoco_total_J` is shifted by that and sum(-m g . r_ref) before it
is compared. `height_m` is the body's clearance above its
reference surface (its lowest point), or, without a clearance, its centre's height above
the reference. The energy budget over flights and contacts: `impactlab.analyze.measure.phases`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import polars as pl

from impactlab.analyze.measure.ground import Ground, Reference, up_vector
from impactlab.analyze.measure.states import state_blocks
from impactlab.logs.load import BodyInfo, RunLog

ENERGY_COLUMNS = ("ke_trans_J", "ke_rot_J", "pe_J", "total_J")
TOTAL_FLAG = "is_total"
"""True on the rows that sum every body of the run (their `body` is "total"), false on a
body's own rows: a body may itself be named "total"."""
ENERGY_ORDER = (
    "run_id",
    "body",
    TOTAL_FLAG,
    "t_ns",
    "t_s",
    "height_m",
    *ENERGY_COLUMNS,
    "mujoco_total_J",
    "mujoco_diff_J",
)
_NOT_TOTAL = pl.lit(False).alias(TOTAL_FLAG)


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


CONSTANTS = (
    "half_m",
    "neg_m",
    "ix",
    "iy",
    "iz",
    "gx",
    "gy",
    "gz",
    "ux",
    "uy",
    "uz",
    "rx",
    "ry",
    "rz",
)
"""Per-row constants of `energy_rows`: m / 2, -m, principal inertia, gravity, the unit
vector against it and the reference point."""


def constants(info: BodyInfo, gravity: np.ndarray, ref: np.ndarray) -> tuple[float, ...]:
    """The values of `CONSTANTS` for one body."""
    m = info.mass
    return (0.5 * m, -m, *info.inertia, *(float(c) for c in gravity), *up_vector(gravity), *ref)


def energy_rows(frame: pl.DataFrame) -> pl.DataFrame:
    """Energy of each state row of `frame` (run_id, body, t_ns, t_s, x .. wz and the
    `CONSTANTS` columns): (run_id, body, t_ns, t_s, height_m, ke_trans_J, ke_rot_J, pe_J,
    total_J); height_m is the centre's height above the reference point along -gravity."""
    c = {name: pl.col(name) for name in CONSTANTS}
    dx, dy, dz = pl.col("x") - c["rx"], pl.col("y") - c["ry"], pl.col("z") - c["rz"]
    return (
        frame.with_columns(body_frame_omega())
        .select(
            "run_id",
            "body",
            "t_ns",
            "t_s",
            (c["ux"] * dx + c["uy"] * dy + c["uz"] * dz).alias("height_m"),
            (c["half_m"] * (pl.col("vx") ** 2 + pl.col("vy") ** 2 + pl.col("vz") ** 2)).alias(
                "ke_trans_J"
            ),
            (
                0.5
                * (
                    c["ix"] * pl.col("wbx") ** 2
                    + c["iy"] * pl.col("wby") ** 2
                    + c["iz"] * pl.col("wbz") ** 2
                )
            ).alias("ke_rot_J"),
            (c["neg_m"] * (c["gx"] * dx + c["gy"] * dy + c["gz"] * dz)).alias("pe_J"),
        )
        .with_columns((pl.col("ke_trans_J") + pl.col("ke_rot_J") + pl.col("pe_J")).alias("total_J"))
    )


def body_energy(
    states: pl.DataFrame, info: BodyInfo, *, gravity: np.ndarray, ref: np.ndarray
) -> pl.DataFrame:
    """Energy of one body at each logged step (`energy_rows`).

    Args:
        states: the body's states (run_id, t_ns, t_s, x .. wz), world frame.
        info: mass (kg) and principal inertia (kg m^2, body frame).
        gravity: (3,) m/s^2.
        ref: (3,) position of zero potential energy, m.
    """
    values = constants(info, gravity, ref)
    n = states.height
    extra = [pl.Series("body", [info.name] * n, dtype=pl.String)]
    extra += [pl.Series(k, np.full(n, v)) for k, v in zip(CONSTANTS, values, strict=True)]
    return energy_rows(states.drop("body", strict=False).hstack(extra))


def run_energies(
    states: pl.DataFrame,
    runs: Sequence[RunLog],
    grounds: Mapping[str, Ground],
    refs: Mapping[str, dict[str, Reference]],
) -> tuple[dict[str, pl.DataFrame], dict[str, pl.DataFrame]]:
    """Each run's energy per body and in all (body "total", `is_total` true), with MuJoCo's
    total compared, and its "total" rows by time.

    Args:
        states: `states_long` of the runs (ids distinct).
        grounds, refs: each run's ground and its bodies' `references`, by run id.

    Returns:
        Per run id: (run_id, body, is_total, t_ns, t_s, height_m, ke_trans_J, ke_rot_J, pe_J,
        total_J, mujoco_total_J, mujoco_diff_J), by body and time; the MuJoCo columns are set on the
        "total" rows only: MuJoCo's total minus sum(-m g . r_ref), and that minus total_J.
        Then per run id its "total" rows, by time. Every body's rows are computed in one set
        of frame operations for all runs.
    """
    by_id = {run.run_id: run for run in runs}
    kept = [(r, b, first, end) for r, b, first, end in state_blocks(states) if b in refs[r]]
    if not kept:
        empty = empty_energy()
        return {run.run_id: empty for run in runs}, {run.run_id: empty for run in runs}
    lengths = np.array([end - first for _, _, first, end in kept])
    frame = states
    if sum(lengths) != states.height:
        frame = states[np.concatenate([np.arange(first, end) for _, _, first, end in kept])]
    values = np.array(
        [
            constants(by_id[r].body_info[b], by_id[r].gravity, refs[r][b].point)
            for r, b, _, _ in kept
        ]
    )
    extra = [pl.Series(k, np.repeat(values[:, i], lengths)) for i, k in enumerate(CONSTANTS)]
    bodies = energy_rows(frame.hstack(extra))
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    bodies = _with_heights(bodies, kept, starts, grounds, refs)
    sums = {c: bodies[c].to_numpy() for c in ("t_ns", "t_s", *ENERGY_COLUMNS)}
    exact = not any(bodies[c].null_count() for c in ENERGY_COLUMNS)
    spans: dict[str, dict[str, tuple[int, int]]] = {}
    for (r, b, _, _), at, n in zip(kept, starts, lengths, strict=True):
        spans.setdefault(r, {})[b] = (int(at), int(at + n))
    summed, slow = [], {}  # runs summed over arrays; the others by a group-by
    for r, mine in spans.items():
        run = by_id[r]
        order = [b for b in refs[r] if b in mine]  # the bodies in the order of the metadata
        shift = float(sum(-run.body_info[n].mass * run.gravity @ refs[r][n].point for n in refs[r]))
        shift += run.static_potential_J  # MuJoCo counts the static bodies' mass too
        cols = [{c: v[a:z] for c, v in sums.items()} for a, z in (mine[b] for b in order)]
        if exact and all(
            np.array_equal(f["t_ns"], cols[0]["t_ns"]) and np.array_equal(f["t_s"], cols[0]["t_s"])
            for f in cols
        ):  # every body logged at the same times: sums over the arrays, in the bodies' order
            total = {c: cols[0][c] for c in ENERGY_COLUMNS}
            for f in cols[1:]:
                total = {c: total[c] + f[c] for c in ENERGY_COLUMNS}
            total = _with_joints(total, run.joint_energy, cols[0]["t_ns"])
            theirs, found = _mujoco_at(run.energy, cols[0]["t_ns"], shift)
            summed.append((r, cols[0]["t_ns"], cols[0]["t_s"], total, theirs, found))
        else:
            parts = [bodies.slice(mine[b][0], mine[b][1] - mine[b][0]) for b in order]
            slow[r] = total_energy(parts, run.energy, shift, run.joint_energy)
    by_run = _totals(summed) | slow
    totals = [by_run[r] for r in spans]
    out = _by_run(bodies, spans, totals)
    by_time = {
        r: t if t["t_ns"].is_sorted() else t.sort("t_ns")
        for r, t in zip(spans, totals, strict=True)
    }
    empty = empty_energy()
    return (
        {run.run_id: out.get(run.run_id, empty) for run in runs},
        {run.run_id: by_time.get(run.run_id, empty) for run in runs},
    )


def _by_run(
    bodies: pl.DataFrame,
    spans: dict[str, dict[str, tuple[int, int]]],
    totals: list[pl.DataFrame],
) -> dict[str, pl.DataFrame]:
    """Each run's energy frame (`ENERGY_ORDER`): its bodies by name, the sum's rows
    (`is_total`) where "total" sorts among them; slices of one frame of every run's bodies
    and of each run's sums, with their columns set once."""
    no_mujoco = [pl.lit(None, dtype=pl.Float64).alias(c) for c in ENERGY_ORDER[-2:]]
    every = bodies.with_columns(_NOT_TOTAL, *no_mujoco).select(ENERGY_ORDER)
    sums = pl.concat(totals, rechunk=False) if totals else every.clear()
    sums = sums.with_columns(pl.lit(True).alias(TOTAL_FLAG)).select(ENERGY_ORDER)
    at = np.cumsum([0, *(t.height for t in totals)])
    out = {}
    for i, (r, mine) in enumerate(spans.items()):
        total: pl.DataFrame | None = sums.slice(int(at[i]), totals[i].height)
        frames = []
        for b in sorted(mine):
            if b >= "total" and total is not None:  # the sum's rows before a body named total
                frames.append(total)
                total = None
            first, end = mine[b]
            frames.append(every.slice(first, end - first))
        if total is not None:
            frames.append(total)
        out[r] = pl.concat(frames, rechunk=False)
    return out


def _with_heights(
    bodies: pl.DataFrame,
    kept: list[tuple[str, str, int, int]],
    starts: np.ndarray,
    grounds: Mapping[str, Ground],
    refs: Mapping[str, dict[str, Reference]],
) -> pl.DataFrame:
    """Heights above the reference surface where the body has one: its clearance (null where
    the log has none)."""
    measured = [(i, r, b) for i, (r, b, _, _) in enumerate(kept) if refs[r][b].surface is not None]
    if not measured:
        return bodies
    height = bodies["height_m"].to_numpy().copy()
    found = np.ones(height.size, dtype=bool)
    t_ns = bodies["t_ns"].to_numpy()
    for i, r, b in measured:
        first, end = int(starts[i]), int(starts[i]) + kept[i][3] - kept[i][2]
        surface = refs[r][b].surface
        height[first:end], found[first:end] = grounds[r].clearance_at(b, surface, t_ns[first:end])
    return bodies.with_columns(with_nulls("height_m", height, found))


def with_nulls(name: str, values: np.ndarray, found: np.ndarray) -> pl.Series:
    """`values` as a Float64 column, null where not `found`."""
    column = pl.Series(name, values, dtype=pl.Float64)
    return column.scatter(np.flatnonzero(~found), None) if not found.all() else column


def total_energy(
    bodies: list[pl.DataFrame],
    mujoco: pl.DataFrame,
    shift: float,
    joints: pl.DataFrame | None = None,
) -> pl.DataFrame:
    """The run's "total" rows when its bodies are not all logged at the same times (a
    damaged log): the bodies' energies summed by a group-by at each logged time, plus the
    joints' (`joints`: t_ns, kinetic, potential), and MuJoCo's total (`mujoco`: t_ns, total)
    minus `shift` where it was logged at that time."""
    total = (
        pl.concat(bodies)
        .group_by("run_id", "t_ns", "t_s", maintain_order=True)
        .agg(*[pl.col(c).sum() for c in ENERGY_COLUMNS])
    )
    if joints is not None and joints.height:
        sums = _with_joints(
            {c: total[c].to_numpy() for c in ENERGY_COLUMNS}, joints, total["t_ns"].to_numpy()
        )
        total = total.with_columns(pl.Series(c, v) for c, v in sums.items())
    theirs, found = _mujoco_at(mujoco, total["t_ns"].to_numpy(), shift)
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


def _totals(
    summed: list[tuple[str, np.ndarray, np.ndarray, dict[str, np.ndarray], np.ndarray, np.ndarray]],
) -> dict[str, pl.DataFrame]:
    """The "total" rows of runs summed over arrays (run id, t_ns, t_s, the sums, MuJoCo's
    total and where it was logged), built as one frame and split into each run's slice."""
    if not summed:
        return {}
    sizes = [t.size for _, t, *_ in summed]
    n = sum(sizes)
    ids = pl.Series("run_id", [r for r, *_ in summed], dtype=pl.String)
    total_j = np.concatenate([x[3]["total_J"] for x in summed])
    mujoco_total = with_nulls(
        "mujoco_total_J",
        np.concatenate([x[4] for x in summed]),
        np.concatenate([x[5] for x in summed]),
    )
    frame = pl.DataFrame(
        [
            ids.gather(np.repeat(np.arange(len(summed)), sizes)),
            pl.Series("body", ["total"], dtype=pl.String).new_from_index(0, n),
            pl.Series("t_ns", np.concatenate([x[1] for x in summed]), dtype=pl.Int64),
            pl.Series("t_s", np.concatenate([x[2] for x in summed]), dtype=pl.Float64),
            pl.Series("height_m", [None], dtype=pl.Float64).new_from_index(0, n),
            *[
                pl.Series(c, np.concatenate([x[3][c] for x in summed]), dtype=pl.Float64)
                for c in ENERGY_COLUMNS
            ],
            mujoco_total,
            (mujoco_total - pl.Series(total_j)).alias("mujoco_diff_J"),
        ]
    )
    starts = np.cumsum(sizes) - sizes
    return {
        r: frame.slice(int(a), size) for (r, *_), a, size in zip(summed, starts, sizes, strict=True)
    }


def _with_joints(
    total: dict[str, np.ndarray], joints: pl.DataFrame, t: np.ndarray
) -> dict[str, np.ndarray]:
    """The bodies' summed energy plus the joints' at each time of `t`: rotor inertia's
    kinetic energy counts as rotation, springs as potential energy (none logged: unchanged)."""
    if not joints.height:
        return total
    logged = joints["t_ns"].to_numpy()
    spot = np.clip(np.searchsorted(logged, t), 0, logged.size - 1)
    found = logged[spot] == t
    rotor = np.where(found, joints["kinetic"].to_numpy()[spot], np.nan)
    spring = np.where(found, joints["potential"].to_numpy()[spot], np.nan)
    out = dict(total)
    out["ke_rot_J"] = total["ke_rot_J"] + rotor
    out["pe_J"] = total["pe_J"] + spring
    out["total_J"] = total["total_J"] + rotor + spring
    return out


def _mujoco_at(mujoco: pl.DataFrame, t: np.ndarray, shift: float) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's total energy (`mujoco`: t_ns, total) minus `shift` at each time of `t`, and
    whether it was logged there (NaN where not)."""
    logged, values = mujoco["t_ns"].to_numpy(), mujoco["total"].to_numpy()
    nulls = mujoco["total"].has_nulls()
    if not nulls and np.array_equal(logged, t) and bool((t[1:] > t[:-1]).all()):
        # as recorded: one value at each time
        return values - shift, np.ones(t.size, dtype=bool)
    order = np.argsort(logged, kind="stable")
    logged, values = logged[order], values[order]
    found = np.zeros(t.size, dtype=bool)
    theirs = np.full(t.size, np.nan)
    if logged.size:
        spot = np.clip(np.searchsorted(logged, t), 0, logged.size - 1)
        found = logged[spot] == t
        if nulls:
            found &= mujoco["total"].is_not_null().to_numpy()[order][spot]
        theirs[found] = values[spot[found]] - shift
    return theirs, found


def empty_energy() -> pl.DataFrame:
    """An energy frame with no rows."""
    schema = {"run_id": pl.String, "body": pl.String, TOTAL_FLAG: pl.Boolean}
    schema |= {"t_ns": pl.Int64, "t_s": pl.Float64}
    schema |= {c: pl.Float64 for c in ("height_m", *ENERGY_COLUMNS)}
    schema |= {c: pl.Float64 for c in ("mujoco_total_J", "mujoco_diff_J")}
    return pl.DataFrame(schema=schema)
