"""Impact and release speeds at the contact point, exact across logging gaps; chatter merged.

For each raw contact interval (`impactlab.analyze.measure.contact_intervals`):

- **The contact point** is a point of the body: the body's deepest point where it touches
  at the first row in contact (for the impact) and at the last (for the release: the mean
  of the contact points, half the mean penetration below it), carried with the body's
  rotation to the last logged row before the contact (row b) and the first after it (row
  a). Its velocity there is v + w x r (r from the centre of mass), and u is its component
  along the contact normal n (from the surface to the body; for two bodies, body to other).
- **A body on a surface** flies ballistically between row b and the moment the surfaces
  meet. The point's height above the surface's tangent plane (through the surface's side of
  the contact, half the penetration above the mean point) follows
  c(s) = c_b + (u + a h) s + a s^2 / 2, with a = g . n + n . (w x (w x r)) the point's
  normal acceleration (gravity and the rotation's centripetal part) and h the log's
  `half_step_s` (`physics.half_step_s`): dt / 2 for MuJoCo's semi-implicit integrators
  (positions advance with the velocity after each step, which puts the parabola through the
  logged positions half a step late), 0 for RK4. The
  meeting is its first root s* and the impact speed v_in = u + a (h + s*); the release, the
  same backwards from row a: v_out = u + a (h - s*). For a body that does not turn both are
  exact whatever the logging stride; for a turning body, to second order in the gap.
- **Two bodies** fall alike under gravity: their relative normal velocity at the contact
  point is constant in free flight, and is taken at rows b and a.

**Chatter.** A raw interval is followed by a visible flight when the body leaves with
v_out > v_min = (MIN_FLIGHT_ROWS / 2) |g| dt_log, dt_log the time between logged rows
(timestep x logging.every): released at v_out against gravity a body flies 2 v_out / g, so
a slower release is a flight of fewer than MIN_FLIGHT_ROWS logged rows, rising less than
(MIN_FLIGHT_ROWS dt_log)^2 g / 8. Such hops are what a contact at rest, sliding or rolling
does in MuJoCo: its contact flickers at micrometres per second, and a sliding ball hops by
micrometres on the friction pyramid. Raw intervals not followed by a visible flight are
merged with the next one into one contact (`merge_chatter`); an arrival slower than v_min
is no impact. Without gravity v_min is 0: every separation is a flight.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import polars as pl

from impactlab.analyze.measure import kinematics as k
from impactlab.analyze.measure.contact_intervals import PAIR
from impactlab.analyze.measure.ground import Ground
from impactlab.analyze.measure.state_table import States, StateTable
from impactlab.analyze.measure.states import logged_interval_s
from impactlab.logs.load import RunLog

if TYPE_CHECKING:
    from polars._typing import PolarsDataType

MIN_FLIGHT_ROWS = 10
"""A flight the analysis can see lasts at least this many logged intervals."""
NEWTON_STEPS = 4
"""Newton steps refining the meeting time from the parabola (exact at once without turning)."""


def clearance_at(
    grounds: Mapping[str, Ground],
    runs: list[str],
    bodies: list[str],
    surfaces: list[str | None],
    t_ns: np.ndarray,
) -> np.ndarray:
    """Each body's clearance to each surface at each time (NaN where the log has none)."""
    out = np.full(len(bodies), np.nan)
    rows: dict[tuple[str, str, str], list[int]] = {}
    for i, (run, body, surface) in enumerate(zip(runs, bodies, surfaces, strict=True)):
        if surface is not None and np.isfinite(t_ns[i]):
            rows.setdefault((run, body, surface), []).append(i)
    for (run, body, surface), mine in rows.items():
        out[mine] = grounds[run].clearance_at(body, surface, t_ns[mine].astype(np.int64))[0]
    return out


def vectors(cols: dict[str, np.ndarray], prefix: str, suffix: str) -> np.ndarray:
    """The columns `<prefix>x<suffix>` .. `<prefix>z<suffix>` as (n, 3)."""
    return np.column_stack([cols[f"{prefix}{c}{suffix}"] for c in "xyz"])


@dataclass(frozen=True)
class Point:
    """A contact point of one body at one row: r from the centre of mass (n, 3), whether it
    turns with the body, its velocity and centripetal acceleration (n, 3)."""

    r: np.ndarray
    turns: np.ndarray
    v: np.ndarray
    a: np.ndarray


def contact_point(
    frame: dict[str, np.ndarray],
    tag: str,
    at: States,
    contact: States,
    *,
    turns: np.ndarray | None,
    sphere: np.ndarray,
    clearance: np.ndarray | None = None,
) -> tuple[Point, np.ndarray]:
    """The contact point `tag` of one body at the row `at` (see the module docstring), and
    its height above the surface's tangent plane there.

    The point is p_<tag> moved half the mean penetration pen_<tag> against the normal, taken
    relative to the centre of mass at the contact row. As a point of the body (a corner, an
    edge) it turns with the body; as the point below the centre (a sphere: the touching point
    slides over a spinning ball) it does not. Which one: not for a sphere; otherwise the one
    whose height is nearer the clearance MuJoCo measured at that row (turning without it).
    """
    n = vectors(frame, "n", f"_{tag}")
    half = frame[f"pen_{tag}"][:, None] / 2
    p = vectors(frame, "p", f"_{tag}")
    deep, surface = p - half * n, p + half * n
    r_geo = deep - contact.x
    r_mat = k.rotate(at.q, k.rotate(contact.q, r_geo, inverse=True))
    c_mat, c_geo = k.dot(n, at.x + r_mat - surface), k.dot(n, at.x + r_geo - surface)
    if turns is None:
        assert clearance is not None  # which point turns is read from the clearance
        nearer = np.abs(c_mat - clearance) <= np.abs(c_geo - clearance)
        turns = ~sphere & (np.isnan(clearance) | nearer)
    r = np.where(turns[:, None], r_mat, r_geo)
    acc = np.where(turns[:, None], k.cross(at.w, k.cross(at.w, r)), 0.0)
    return Point(r, turns, at.v + k.cross(at.w, r), acc), np.where(turns, c_mat, c_geo)


def reach_surface(
    n: np.ndarray,
    point: Point,
    at: States,
    height: np.ndarray,
    gap: np.ndarray,
    *,
    gravity: np.ndarray,
    h: np.ndarray,
    sign: float,
) -> tuple[np.ndarray, np.ndarray]:
    """When the point reaches the surface's tangent plane from the row `at` (s, signed: after
    the row for an impact, before it for a release, within `gap`) and its normal speed then.

    The centre flies ballistically (with the integrator's half step h), the body turns at its
    angular velocity; the parabola's root is refined by Newton steps. NaN when it never does.
    """
    lo, hi = np.minimum(gap, 0.0), np.maximum(gap, 0.0)
    g_n = k.dot(n, gravity)
    u = k.dot(n, point.v)
    a = g_n + k.dot(n, point.a)
    s = np.clip(sign * k.first_root(height, sign * (u + a * h), a), lo, hi)

    def flight(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r_s = np.where(point.turns[:, None], k.turn(point.r, at.w, s), point.r)
        v_n = k.dot(n, at.v)
        rise = (v_n + g_n * h) * s + g_n * s * s / 2 + k.dot(n, r_s - point.r)
        return height + rise, v_n + g_n * (h + s) + k.dot(n, k.cross(at.w, r_s))

    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(NEWTON_STEPS):
            c, rate = flight(s)
            s = np.clip(s - c / rate, lo, hi)
        return s, flight(s)[1]


def approach_and_release(
    raw: pl.DataFrame,
    states: pl.DataFrame,
    runs: Sequence[RunLog],
    grounds: Mapping[str, Ground],
) -> pl.DataFrame:
    """Add to raw intervals of one or more runs: row_b, row_a, t_b_ns, t_a_ns, v_in_mps,
    v_out_mps, meet_t_s and release_t_s (the moments the surfaces meet and part; null for
    two bodies), v_min_mps and `visible` (a visible flight follows; see the module
    docstring), each body's contact-point velocity along the impact normal at rows b and a
    (u1_b, u2_b, u1_a, u2_a; 1 is `body`, 2 `other` when it is a body) and the lever of the
    impact normal about each centre of mass relative to the point's distance from it
    (lever1, lever2: 0 for a central impact).

    Args:
        raw: `contacts.raw_intervals` of the runs; states: their `contacts.states_long`.
        runs: the runs (gravity, integrator, timestep, logging stride, spheres), ids distinct.
        grounds: each run's ground, by run id.
    """
    n_rows = raw.height
    by_id = {run.run_id: run for run in runs}
    ids = raw["run_id"].to_list()
    mine = [by_id[r] for r in ids]
    gravity = np.array([run.gravity for run in mine], dtype=float).reshape(n_rows, 3)
    h = np.array([run.half_step_s for run in mine])
    v_min = np.array(
        [
            MIN_FLIGHT_ROWS / 2 * float(np.linalg.norm(run.gravity)) * logged_interval_s(run)
            for run in mine
        ]
    )
    first, last = raw["first_row"].to_numpy(), raw["last_row"].to_numpy()
    open_ = raw["open"].fill_null(True).to_numpy().astype(bool)
    rows = {
        "row_b": np.where(first > 0, first - 1.0, np.nan),
        "first_row": first.astype(float),
        "last_row": last.astype(float),
        "row_a": np.where(open_, np.nan, last + 1.0),
    }
    on_ground = (raw["kind"] == "ground").fill_null(False).to_numpy().astype(bool)
    bodies = raw["body"].to_list()
    others = [o if not g else None for o, g in zip(raw["other"].to_list(), on_ground, strict=True)]
    points = raw.select(
        pl.col(c).cast(pl.Float64)
        for c in raw.columns
        if c.endswith(("_in", "_out")) and c[:1] in "pn"
    )
    cols = {c: points[c].to_numpy() for c in points.columns}
    table = StateTable(states)
    at_row = {
        (side, row): table.at(ids, names, rows[row])
        for side, names in (("1", bodies), ("2", others))
        for row in rows
    }
    t_b, t_a = (np.round(at_row[("1", r)].t * 1e9) for r in ("row_b", "row_a"))
    surfaces = [
        None if not g else o for o, g in zip(raw["other"].to_list(), on_ground, strict=True)
    ]
    spheres = {
        (run.run_id, n)
        for run in runs
        for n, info in run.body_info.items()
        if info.radius is not None
    }
    sphere = [
        np.array([(r, b) in spheres for r, b in zip(ids, names, strict=True)], dtype=bool)
        for names in (bodies, others)
    ]
    out: dict[str, np.ndarray] = {}
    speeds = {}
    for tag, at, contact, sign, t_row in (
        ("in", "row_b", "first_row", 1.0, t_b),
        ("out", "row_a", "last_row", -1.0, t_a),
    ):
        n = vectors(cols, "n", f"_{tag}")
        s1, c1 = at_row[("1", at)], at_row[("1", contact)]
        s2, c2 = at_row[("2", at)], at_row[("2", contact)]
        clr = clearance_at(grounds, ids, bodies, surfaces, t_row)
        p1, height = contact_point(cols, tag, s1, c1, turns=None, sphere=sphere[0], clearance=clr)
        p2, _ = contact_point(cols, tag, s2, c2, turns=~sphere[1], sphere=sphere[1])
        s, rate = reach_surface(n, p1, s1, height, c1.t - s1.t, gravity=gravity, h=h, sign=sign)
        found = on_ground & np.isfinite(s)
        relative = k.dot(n, p2.v - p1.v)
        out[f"v_{tag}_mps"] = np.where(on_ground, np.where(found, rate, k.dot(n, p1.v)), relative)
        out["meet_t_s" if tag == "in" else "release_t_s"] = np.where(found, s1.t + s, np.nan)
        speeds[tag] = (p1, p2)
        if tag == "in":  # the lever of the impact normal about each centre of mass
            for i, c in enumerate((c1, c2), start=1):
                r = vectors(cols, "p", "_in") - c.x
                with np.errstate(divide="ignore", invalid="ignore"):
                    lever = np.linalg.norm(k.cross(r, n), axis=1) / np.linalg.norm(r, axis=1)
                out[f"lever{i}"] = lever
    n_in = vectors(cols, "n", "_in")
    for i in (0, 1):  # each body's point velocity along the impact normal, at rows b and a
        out[f"u{i + 1}_b"] = k.dot(n_in, speeds["in"][i].v)
        out[f"u{i + 1}_a"] = k.dot(n_in, speeds["out"][i].v)
    visible = ~open_ & np.isfinite(out["v_out_mps"]) & (out["v_out_mps"] > v_min)

    def series(name: str, values: np.ndarray, dtype: PolarsDataType = pl.Float64) -> pl.Series:
        column = pl.Series(name, np.where(np.isfinite(values), values, np.nan), nan_to_null=True)
        return column if dtype == pl.Float64 else column.cast(dtype)

    added = pl.DataFrame(
        [
            series("row_b", rows["row_b"], pl.Int64),
            series("row_a", rows["row_a"], pl.Int64),
            series("t_b_ns", t_b, pl.Int64),
            series("t_a_ns", t_a, pl.Int64),
            *[series(name, out[name]) for name in ("v_in_mps", "v_out_mps", "meet_t_s")],
            series("release_t_s", out["release_t_s"]),
            pl.Series("v_min_mps", v_min, dtype=pl.Float64),
            pl.Series("visible", visible),
            *[series(name, out[name]) for name in ("u1_b", "u2_b", "u1_a", "u2_a")],
            *[series(name, out[name]) for name in ("lever1", "lever2")],
        ]
    )
    return pl.concat([raw, added], how="horizontal")


def merge_chatter(intervals: pl.DataFrame) -> pl.DataFrame:
    """Merge raw intervals not followed by a visible flight with the next one of their pair.

    `intervals` may hold several runs (distinct `run_id`s): each run's contacts are merged
    on their own, and the result is by run, then by time.

    Returns:
        One row per contact, with the first raw interval's impact (first_row, start_t_ns,
        row_b, t_b_ns, v_in_mps, meet_t_s, the `_in` point and normal) and the last one's
        release (last_row, end_t_ns, row_a, t_a_ns, v_out_mps, release_t_s, the `_out` point
        and normal, v_min_mps, visible, open); peak force and penetration the maxima, impulse
        and n_steps the sums, `n_raw` the raw intervals merged; `interval` renumbered.
    """
    pair = list(PAIR)
    first = ["first_row", "start_t_ns", "row_b", "t_b_ns", "v_in_mps", "meet_t_s"]
    first += ["u1_b", "u2_b", "lever1", "lever2"]
    first += [f"{c}_in" for c in ("px", "py", "pz", "nx", "ny", "nz")]
    last = ["last_row", "end_t_ns", "row_a", "t_a_ns", "v_out_mps", "release_t_s"]
    last += ["u1_a", "u2_a"]
    last += [f"{c}_out" for c in ("px", "py", "pz", "nx", "ny", "nz")]
    last += ["v_min_mps", "visible", "open"]
    return (
        intervals.sort("run_id", *pair, "first_row")
        .with_columns(
            pl.col("visible")
            .shift(1)
            .fill_null(False)
            .cast(pl.Int64)
            .cum_sum()
            .over("run_id", *pair)
            .alias("merged")
        )
        .group_by("run_id", *pair, "merged", maintain_order=True)
        .agg(
            *[pl.col(c).first() for c in first],
            *[pl.col(c).last() for c in last],
            pl.col("n_steps").sum(),
            pl.col("peak_force_N").max(),
            pl.col("impulse_Ns").sum(),
            pl.col("max_penetration_m").max(),
            pl.len().alias("n_raw"),
        )
        .rename({"merged": "interval"})
        .sort("run_id", "start_t_ns", *pair)
    )
