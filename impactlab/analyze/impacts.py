"""Impact and release speeds at the contact point, exact across logging gaps; chatter merged.

For each raw contact interval (`impactlab.analyze.contacts`):

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
  normal acceleration (gravity and the rotation's centripetal part) and h = dt / 2 for
  MuJoCo's semi-implicit integrators (positions advance with the velocity after each step,
  which puts the parabola through the logged positions half a step late), 0 for RK4. The
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

import numpy as np
import polars as pl

from impactlab.analyze import kinematics as k
from impactlab.analyze.contacts import PAIR, state_at

RK4 = "RK4"
MIN_FLIGHT_ROWS = 10
"""A flight the analysis can see lasts at least this many logged intervals."""
NEWTON_STEPS = 4
"""Newton steps refining the meeting time from the parabola (exact at once without turning)."""


def point_motion(frame: pl.DataFrame, at: str, contact: str, side: str, tag: str) -> pl.DataFrame:
    """Add, for the body whose states carry suffix `side + at` (the row of interest) and
    `side + contact` (the contact row), where its contact point `tag` is at the row `at`.

    The point is p_<tag> moved half the mean penetration pen_<tag> against the normal, taken
    relative to the centre of mass at the contact row. As a point of the body (a corner, an
    edge) it turns with the body: rm<xyz><side><tag> at the row `at`; as the point below the
    centre (a ball rolling or spinning: the touching point slides over the body) it does not:
    rg<xyz><side><tag>. For side 1 its heights above the surface's tangent plane at the row
    `at` are cm<tag> and cg<tag> (turning with the body, or not).
    """
    n = k.vec("n", f"_{tag}")
    half = pl.col(f"pen_{tag}") / 2
    deep = [pl.col(f"p{c}_{tag}") - half * n[i] for i, c in enumerate("xyz")]
    r_geo = k.sub(deep, k.vec("", f"{side}{contact}"))
    r_body = k.rotate(f"{side}{contact}", r_geo, inverse=True)
    frame = frame.with_columns(
        *k.named(r_body, "rb", f"{side}{tag}"), *k.named(r_geo, "rg", f"{side}{tag}")
    )
    r_mat = k.rotate(f"{side}{at}", k.vec("rb", f"{side}{tag}"))
    extra = []
    if side == "1":
        surface = [pl.col(f"p{c}_{tag}") + half * n[i] for i, c in enumerate("xyz")]
        for name, r in (("m", r_mat), ("g", k.vec("rg", f"{side}{tag}"))):
            point = k.add(k.vec("", f"{side}{at}"), r)
            extra.append(k.dot(n, k.sub(point, surface)).alias(f"c{name}{tag}"))
    return frame.with_columns(*k.named(r_mat, "rm", f"{side}{tag}"), *extra)


def choose_point(frame: pl.DataFrame, side: str, tag: str, at: str, spheres: list[str]):
    """Add the contact point used (r<xyz><side><tag>), its velocity (vp..), centripetal
    acceleration (ap..) and, for side 1, its height c<tag> and whether it turns with the body
    (`turns<side><tag>`): not for a sphere; for another body on a surface, when turning with it
    puts the point nearer the clearance MuJoCo measured at that row."""
    body = pl.col("body" if side == "1" else "body2")
    sphere = body.is_in(spheres)
    if side == "1":
        clearance = pl.col(f"clr{tag}")
        nearer = (pl.col(f"cm{tag}") - clearance).abs() <= (pl.col(f"cg{tag}") - clearance).abs()
        turns = ~sphere & (clearance.is_null() | nearer)
    else:
        turns = ~sphere
    frame = frame.with_columns(turns.fill_null(True).alias(f"turns{side}{tag}"))
    turning = pl.col(f"turns{side}{tag}")
    r = [
        pl.when(turning).then(m).otherwise(g_)
        for m, g_ in zip(k.vec("rm", f"{side}{tag}"), k.vec("rg", f"{side}{tag}"), strict=True)
    ]
    w = k.vec("w", f"{side}{at}")
    v = k.add(k.vec("v", f"{side}{at}"), k.cross(w, r))
    acc = [pl.when(turning).then(a).otherwise(0.0) for a in k.cross(w, k.cross(w, r))]
    extra = []
    if side == "1":
        extra.append(
            pl.when(turning).then(pl.col(f"cm{tag}")).otherwise(pl.col(f"cg{tag}")).alias(f"c{tag}")
        )
    return frame.with_columns(
        *k.named(r, "r", f"{side}{tag}"),
        *k.named(v, "vp", f"{side}{tag}"),
        *k.named(acc, "ap", f"{side}{tag}"),
        *extra,
    )


def approach_and_release(
    raw: pl.DataFrame,
    states: pl.DataFrame,
    clearance: pl.DataFrame,
    *,
    spheres: list[str],
    gravity: np.ndarray,
    integrator: str,
    timestep_s: float,
    interval_s: float,
) -> pl.DataFrame:
    """Add to raw intervals: row_b, row_a, t_b_ns, t_a_ns, v_in_mps, v_out_mps, meet_t_s
    and release_t_s (the moments the surfaces meet and part; null for two bodies), v_min_mps
    and `visible` (a visible flight follows; see the module docstring), each body's
    contact-point velocity along the impact normal at rows b and a (u1_b, u2_b, u1_a, u2_a;
    1 is `body`, 2 `other` when it is a body) and the lever of the impact normal about each
    centre of mass relative to the point's distance from it (lever1, lever2: 0 for a central
    impact)."""
    h = 0.0 if integrator == RK4 else timestep_s / 2
    frame = raw.with_columns(
        pl.when(pl.col("first_row") > 0).then(pl.col("first_row") - 1).alias("row_b"),
        pl.when(~pl.col("open")).then(pl.col("last_row") + 1).alias("row_a"),
        pl.when(pl.col("kind") == "body").then(pl.col("other")).alias("body2"),
    )
    for side, name in (("1", "body"), ("2", "body2")):
        for at, row in (("_b", "row_b"), ("_f", "first_row"), ("_l", "last_row"), ("_a", "row_a")):
            frame = state_at(states, frame, body=name, row=row, suffix=f"{side}{at}")
    frame = with_clearance(frame, clearance)
    for tag, at, contact in (("in", "_b", "_f"), ("out", "_a", "_l")):
        for side in ("1", "2"):
            frame = point_motion(frame, at, contact, side, tag)
            frame = choose_point(frame, side, tag, at, spheres)
    g = [pl.lit(float(x)) for x in gravity]
    ground = pl.col("kind") == "ground"
    out = []
    for tag, at, contact, sign in (("in", "_b", "_f", 1.0), ("out", "_a", "_l", -1.0)):
        n = k.vec("n", f"_{tag}")
        u_body = k.dot(n, k.vec("vp", f"1{tag}"))
        a = k.dot(n, g) + k.dot(n, k.vec("ap", f"1{tag}"))
        gap = (pl.col(f"t_ns1{contact}") - pl.col(f"t_ns1{at}")) / 1e9  # signed
        first = sign * k.first_root(pl.col(f"c{tag}"), sign * (u_body + a * h), a)
        frame = frame.with_columns(first.clip(*sorted_bounds(gap)).alias(f"s{tag}"))
        for _ in range(NEWTON_STEPS):
            c, dc = flight_height(tag, at, g, h)
            step = pl.col(f"s{tag}") - c / dc
            frame = frame.with_columns(step.clip(*sorted_bounds(gap)).alias(f"s{tag}"))
        u_rel = k.dot(n, k.sub(k.vec("vp", f"2{tag}"), k.vec("vp", f"1{tag}")))
        found = pl.col(f"s{tag}").is_not_null()
        speed = pl.when(~ground).then(u_rel).when(found).then(flight_height(tag, at, g, h)[1])
        t_row = pl.col(f"t_ns1{at}") / 1e9
        moment = pl.when(ground & found).then(t_row + pl.col(f"s{tag}"))
        out += [
            speed.otherwise(u_body).alias(f"v_{tag}_mps"),
            moment.alias("meet_t_s" if tag == "in" else "release_t_s"),
        ]
    n_in = k.vec("n", "_in")
    for side in ("1", "2"):  # each body's point velocity along the impact normal, at b and a
        out += [
            k.dot(n_in, k.vec("vp", f"{side}in")).alias(f"u{side}_b"),
            k.dot(n_in, k.vec("vp", f"{side}out")).alias(f"u{side}_a"),
        ]
        r = k.vec("rb", f"{side}in")  # lever of the normal about the centre of mass
        out.append(
            (k.norm(k.cross(r, k.rotate(f"{side}_f", n_in, inverse=True))) / k.norm(r)).alias(
                f"lever{side}"
            )
        )
    v_min = pl.lit(MIN_FLIGHT_ROWS / 2 * float(np.linalg.norm(gravity)) * interval_s)
    frame = frame.with_columns(*out, v_min.alias("v_min_mps")).with_columns(
        (
            ~pl.col("open")
            & pl.col("v_out_mps").is_not_null()
            & (pl.col("v_out_mps") > pl.col("v_min_mps"))
        ).alias("visible"),
        pl.col("t_ns1_b").alias("t_b_ns"),
        pl.col("t_ns1_a").alias("t_a_ns"),
    )
    return frame.select(
        *raw.columns,
        "row_b",
        "row_a",
        "t_b_ns",
        "t_a_ns",
        "v_in_mps",
        "v_out_mps",
        "meet_t_s",
        "release_t_s",
        "v_min_mps",
        "visible",
        "u1_b",
        "u2_b",
        "u1_a",
        "u2_a",
        "lever1",
        "lever2",
    )


def with_clearance(frame: pl.DataFrame, clearance: pl.DataFrame) -> pl.DataFrame:
    """Add clrin and clrout: the body's clearance to the surface `other` at rows b and a."""
    for col, t in (("clrin", "t_ns1_b"), ("clrout", "t_ns1_a")):
        right = clearance.select(
            "body",
            pl.col("surface").alias("other"),
            pl.col("t_ns").alias(t),
            pl.col("clearance_m").alias(col),
        )
        frame = frame.join(right, on=["body", "other", t], how="left")
    return frame


def sorted_bounds(gap: pl.Expr) -> tuple[pl.Expr, pl.Expr]:
    """(lower, upper) bounds of a signed time s between 0 and `gap`."""
    return pl.min_horizontal(gap, pl.lit(0.0)), pl.max_horizontal(gap, pl.lit(0.0))


def flight_height(tag: str, at: str, g: k.Vec, h: float) -> tuple[pl.Expr, pl.Expr]:
    """The contact point's height above the tangent plane s seconds after the row `at`
    (column s<tag>), and its rate: the centre in free flight; a point that turns with the body
    turns at the body's constant angular velocity w (Rodrigues' rotation by |w| s about w)."""
    s = pl.col(f"s{tag}")
    n = k.vec("n", f"_{tag}")
    r = k.vec("r", f"1{tag}")
    w = k.vec("w", f"1{at}")
    v = k.vec("v", f"1{at}")
    size = k.norm(w)
    axis = [pl.when(size > 0).then(w[i] / size).otherwise(0.0) for i in range(3)]
    cos, sin = (size * s).cos(), (size * s).sin()
    along = k.dot(axis, r)
    side = k.cross(axis, r)
    turning = pl.col(f"turns1{tag}")
    r_s = [
        pl.when(turning)
        .then(r[i] * cos + side[i] * sin + axis[i] * along * (1 - cos))
        .otherwise(r[i])
        for i in range(3)
    ]
    g_n = k.dot(n, g)
    height = (
        pl.col(f"c{tag}") + (k.dot(n, v) + g_n * h) * s + g_n * s * s / 2 + k.dot(n, k.sub(r_s, r))
    )
    rate = k.dot(n, v) + g_n * (h + s) + k.dot(n, k.cross(w, r_s))
    return height, rate


def merge_chatter(intervals: pl.DataFrame) -> pl.DataFrame:
    """Merge raw intervals not followed by a visible flight with the next one of their pair.

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
        intervals.sort(*pair, "first_row")
        .with_columns(
            pl.col("visible")
            .shift(1)
            .fill_null(False)
            .cast(pl.Int64)
            .cum_sum()
            .over(pair)
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
        .sort("start_t_ns", *pair)
    )
