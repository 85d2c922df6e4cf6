"""Energy of each body and of the run: kinetic (translational, rotational), potential, total
(the references and MuJoCo's shift: docs/analysis.md)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import polars as pl

from impactlab.analyze.measure.ground import Ground, Reference
from impactlab.analyze.measure.states import at_times, by_run, state_blocks
from impactlab.logs.load import BodyInfo, RunLog
from impactlab.physics import up_vector

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
    spans: dict[str, dict[str, tuple[int, int]]] = {}
    for (r, b, _, _), at, n in zip(kept, starts, lengths, strict=True):
        spans.setdefault(r, {})[b] = (int(at), int(at + n))
    code = np.repeat([list(spans).index(r) for r, _, _, _ in kept], lengths)
    total = _totals(bodies, code, frame["row"].to_numpy(), [by_id[r] for r in spans], refs)
    totals = by_run(total)
    out = _by_run(bodies, spans, [totals[r] for r in spans])
    empty = empty_energy()
    return (
        {run.run_id: out.get(run.run_id, empty) for run in runs},
        {run.run_id: totals.get(run.run_id, empty) for run in runs},
    )


def _totals(
    bodies: pl.DataFrame,
    run: np.ndarray,
    row: np.ndarray,
    runs: Sequence[RunLog],
    refs: Mapping[str, dict[str, Reference]],
) -> pl.DataFrame:
    """The runs' "total" rows: their bodies' energies summed at each logged row (`run`: each
    body row's index in `runs`, in order; `row`: its row as `states_long` numbers them, the
    run's distinct logged times in order), plus the joints' where the run logs them (rotor
    inertia's kinetic energy counts as rotation, springs as potential energy; NaN at a time
    without them), and MuJoCo's total minus sum(-m g . r_ref) and the static bodies'
    potential energy (null where not logged)."""
    size = np.zeros(len(runs), np.int64)
    np.maximum.at(size, run, row + 1)
    ends = np.cumsum(size)
    at = (ends - size)[run] + row
    t_ns, t_s = np.zeros(ends[-1], np.int64), np.zeros(ends[-1])
    t_ns[at], t_s[at] = bodies["t_ns"].to_numpy(), bodies["t_s"].to_numpy()
    sums = {c: np.bincount(at, bodies[c].to_numpy(), minlength=ends[-1]) for c in ENERGY_COLUMNS}
    theirs = np.full(t_ns.size, np.nan)
    for r, end, n in zip(runs, ends, size, strict=True):
        mine = slice(end - n, end)
        shift = r.static_potential_J  # MuJoCo counts the static bodies' mass too
        shift += sum(
            -r.body_info[b].mass * r.gravity @ ref.point for b, ref in refs[r.run_id].items()
        )
        theirs[mine] = at_times(t_ns[mine], r.energy, "total") - shift
        if r.joint_energy.height:
            rotor = at_times(t_ns[mine], r.joint_energy, "kinetic")
            spring = at_times(t_ns[mine], r.joint_energy, "potential")
            sums["ke_rot_J"][mine] += rotor
            sums["pe_J"][mine] += spring
            sums["total_J"][mine] += rotor + spring
    ids = pl.Series("run_id", [r.run_id for r in runs], dtype=pl.String)
    mujoco = pl.Series("mujoco_total_J", theirs, nan_to_null=True)
    return pl.DataFrame(
        [
            ids.gather(np.repeat(np.arange(len(runs)), size)),
            pl.Series("body", ["total"], dtype=pl.String).new_from_index(0, t_ns.size),
            pl.Series("t_ns", t_ns),
            pl.Series("t_s", t_s),
            pl.Series("height_m", [None], dtype=pl.Float64).new_from_index(0, t_ns.size),
            *[pl.Series(c, v) for c, v in sums.items()],
            mujoco,
            (mujoco - pl.Series(sums["total_J"])).alias("mujoco_diff_J"),
        ]
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
    sums = pl.concat(totals, rechunk=False).with_columns(pl.lit(True).alias(TOTAL_FLAG))
    sums = sums.select(ENERGY_ORDER)
    at = np.cumsum([0, *(t.height for t in totals)])
    out = {}
    for i, (r, mine) in enumerate(spans.items()):
        # by name, the sum's rows before a body named "total"
        parts = {(b, True): every.slice(first, end - first) for b, (first, end) in mine.items()}
        parts["total", False] = sums.slice(int(at[i]), totals[i].height)
        out[r] = pl.concat([parts[k] for k in sorted(parts)], rechunk=False)
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
    column = pl.Series("height_m", height, dtype=pl.Float64)
    return bodies.with_columns(column.scatter(np.flatnonzero(~found), None))


def empty_energy() -> pl.DataFrame:
    """An energy frame with no rows."""
    schema = {"run_id": pl.String, "body": pl.String, TOTAL_FLAG: pl.Boolean}
    schema |= {"t_ns": pl.Int64, "t_s": pl.Float64}
    schema |= {c: pl.Float64 for c in ("height_m", *ENERGY_COLUMNS)}
    schema |= {c: pl.Float64 for c in ("mujoco_total_J", "mujoco_diff_J")}
    return pl.DataFrame(schema=schema)
