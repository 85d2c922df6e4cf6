"""The measurement written plainly, one run and one body at a time: the tests' oracle.

The batched analysis (`analysis.analyze_runs`) computes every quantity of many runs in one
set of frame operations, which is fast and hard to read. This module computes the same
physics for one run with numpy and loops, in the words of `docs/analysis.md`, so a test can
hold the batched frames against it:

- **Energy** of a body at each logged step: 0.5 m |v|^2 + 0.5 sum_i I_i (R' w)_i^2 (R the
  body's orientation, I its principal inertia) and -m g . x, from its centre of mass.
- **Contacts** of a body with a surface: runs of consecutive logged steps on which the log
  holds a contact of the pair.
- **Impact and release speeds** of a ball (a sphere at its centre of mass: its lowest point
  does not turn with it) on a flat surface: from the last logged step before the contact,
  the lowest point's height c above the surface follows c + (u + a h) s + a s^2 / 2 (u its
  normal velocity, a = g . n, h = dt / 2 for MuJoCo's semi-implicit integrators, 0 for
  RK4) until it reaches 0; v_in = u + a (h + s). The release is the same backwards from the
  first logged step after the contact; e = -v_out / v_in.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from impactlab.logs.load import RunLog


def body_energy(run: RunLog, body: str) -> dict[str, np.ndarray]:
    """Kinetic (translation, rotation) and potential energy of one body at each logged step,
    J; potential energy relative to the body's first logged position."""
    info, states = run.body_info[body], run.bodies[body]
    x = states.select("x", "y", "z").to_numpy()
    v = states.select("vx", "vy", "vz").to_numpy()
    w = states.select("wx", "wy", "wz").to_numpy()
    q = states.select("qw", "qx", "qy", "qz").to_numpy()
    inertia = np.asarray(info.inertia)
    ke_rot = np.empty(len(q))
    for i in range(len(q)):
        w_body = _matrix(q[i]).T @ w[i]
        ke_rot[i] = 0.5 * float(inertia @ w_body**2)
    return {
        "ke_trans_J": 0.5 * info.mass * (v**2).sum(axis=1),
        "ke_rot_J": ke_rot,
        "pe_J": -info.mass * (x - x[0]) @ run.gravity,
    }


def _matrix(q: np.ndarray) -> np.ndarray:
    """The rotation matrix of a unit quaternion (w, x, y, z): body to world."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


@dataclass(frozen=True)
class Contact:
    """Logged steps first..last (row indices of the body's states) in contact with a surface,
    and its normal (from the surface to the body) at the first."""

    body: str
    surface: str
    first: int
    last: int
    normal: np.ndarray


def ground_contacts(run: RunLog, body: str) -> list[Contact]:
    """The body's contacts with the static geoms, in time order (runs of logged steps)."""
    t = run.bodies[body]["t_ns"].to_numpy()
    mine = run.contacts.filter((pl.col("body2") == body) & (pl.col("body1") == "world"))
    out = []
    for (surface,), frame in mine.group_by("geom1", maintain_order=True):
        rows = np.searchsorted(t, np.unique(frame["t_ns"].to_numpy()))
        cuts = np.flatnonzero(np.diff(rows) > 1)
        for lo, hi in zip(np.r_[0, cuts + 1], np.r_[cuts, rows.size - 1], strict=True):
            first = frame.filter(pl.col("t_ns") == t[rows[lo]]).row(0, named=True)
            normal = np.array([first["nx"], first["ny"], first["nz"]])
            out.append(Contact(body, str(surface), int(rows[lo]), int(rows[hi]), normal))
    return sorted(out, key=lambda c: c.first)


def ball_speeds(run: RunLog, contact: Contact) -> tuple[float | None, float | None]:
    """(v_in, v_out) of a ball's contact, m/s (see the module docstring); None where the log
    has no step before (after) it."""
    states = run.bodies[contact.body]
    radius = run.body_info[contact.body].radius
    assert radius is not None, "a ball: one sphere at its centre of mass"
    n, g = contact.normal, run.gravity
    h = run.half_step_s
    level = _surface_level(run, contact)

    def speed(row: int, sign: float) -> float:
        s = states.row(row, named=True)
        height = float(n @ [s["x"], s["y"], s["z"]]) - radius - level
        u, a = float(n @ [s["vx"], s["vy"], s["vz"]]), float(n @ g)
        # height + (u + a h) t + a t^2 / 2 = 0, the root after the row (before it: sign -1)
        b = u + a * h
        roots = np.roots([a / 2, b, height]) if a else np.array([-height / b])
        real = sorted(float(r.real) for r in np.atleast_1d(roots) if abs(r.imag) < 1e-12)
        t = min((r for r in real if sign * r >= 0), key=abs)
        return u + a * (h + t)

    before = speed(contact.first - 1, 1.0) if contact.first > 0 else None
    after = speed(contact.last + 1, -1.0) if contact.last + 1 < states.height else None
    return before, after


def _surface_level(run: RunLog, contact: Contact) -> float:
    """The surface's plane along its normal: the contact point's, half the penetration up."""
    rows = run.contacts.filter(
        (pl.col("body2") == contact.body)
        & (pl.col("geom1") == contact.surface)
        & (pl.col("t_ns") == run.bodies[contact.body]["t_ns"][contact.first])
    ).row(0, named=True)
    point = np.array([rows["x"], rows["y"], rows["z"]])
    return float(contact.normal @ point) + float(rows["penetration"]) / 2
