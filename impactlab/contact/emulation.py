"""Exact numpy emulations of `mj_step` (semi-implicit Euler) for one impact of this contact.

In units w0 = sqrt(stiffness) = 1 and impact speed = 1; the tests check them against MuJoCo
step by step.
"""

from __future__ import annotations

import numpy as np

IMPEDANCE = 0.9999
"""solimp dmin = dmax: MuJoCo's largest impedance (mjMAXIMP). With the direct solref, MuJoCo
uses K = stiffness / d^2 and B = damping / d, so the contact acceleration is exactly
-stiffness * dist - damping * dist_dot + (1 - d) * a_free."""


SOLIMP: tuple[float, float, float, float, float] = (IMPEDANCE, IMPEDANCE, 0.001, 0.5, 2.0)
"""Constant impedance: with dmin = dmax, width, midpoint and power have no effect."""


def emulate_impact(
    zeta: np.ndarray,
    w0dt: float,
    phases: np.ndarray,
    gravity_ratio: float = 0.0,
    impedance: float = IMPEDANCE,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact emulation of mj_step (semi-implicit Euler) for one impact, in units w0 = v_in = 1.

    The first contact step starts at dist = -phase * w0dt (phase in (0, 1]) with velocity -1.
    Per step: aref = -(b u + k y) / d; the constraint is active iff dist < 0 and aref > a_free;
    then a = d aref + (1 - d) a_free, else a = a_free = -gravity_ratio.

    Args:
        zeta: damping ratios, shape (nz,).
        w0dt: w0 * timestep.
        phases: contact-onset phases, shape (nph,).
        gravity_ratio: g / (w0 v_in).
        impedance: solimp d.

    Returns:
        e (nz x nph): velocity after the last force step / v_in;
        penetration (nz x nph): max overlap * w0 / v_in;
        steps (nz x nph): number of steps with a positive force.
    """
    zeta = np.asarray(zeta, float)[:, None]
    ph = np.asarray(phases, float)[None, :]
    shape = np.broadcast_shapes(zeta.shape, ph.shape)
    y = np.broadcast_to(-ph * w0dt, shape).copy()
    u = -np.ones(shape)
    b = np.broadcast_to(2.0 * zeta, shape)
    a_free = -gravity_ratio
    u_out = np.zeros(shape)
    pen = np.zeros(shape)
    steps = np.zeros(shape, dtype=np.int64)
    started = np.zeros(shape, bool)
    done = np.zeros(shape, bool)
    for _ in range(int(40.0 / w0dt) + 100):
        aref = -(b * u + y) / impedance
        force = (y < 0.0) & (aref > a_free) & ~done
        done |= started & ~force
        if done.all():
            break
        a = np.where(force, impedance * aref + (1.0 - impedance) * a_free, a_free)
        pen = np.maximum(pen, np.where(force, -y, 0.0))
        u = u + w0dt * a
        y = y + w0dt * u
        pen = np.maximum(pen, np.where(force, -y, 0.0))
        started |= force
        steps += force
        u_out = np.where(force, u, u_out)
    return u_out, pen, steps


def emulate_surface(
    zeta: float,
    w0dt: float,
    phases: np.ndarray,
    gravity_ratio: float | np.ndarray = 0.0,
    impedance: float = IMPEDANCE,
    t_max: float = 40.0,
) -> tuple[np.ndarray, np.ndarray]:
    """mj_step emulation of one impact, continued until the ball is back at the surface.

    Units w0 = 1 and v_in = 1, v_in being the speed in the last state before the overlap (what
    the analysis stage takes): the first overlapping state has velocity -(1 + w0dt * gr) and
    dist = -phase * w0dt * (1 + w0dt * gr), phase in (0, 1]. Each step applies MuJoCo's rule
    (the constraint pushes while dist < 0 and aref > a_free), also after the force has let go,
    until the first state with dist >= 0.

    Args:
        zeta: damping ratio.
        w0dt: w0 * timestep.
        phases: contact-onset phases, shape (n,).
        gravity_ratio: g / (w0 v_in), scalar or shape (n,).
        impedance: solimp d.
        t_max: give up (e = 0: the ball does not leave) after this time, in 1 / w0.

    Returns:
        (release, surface), each shape (n,): the velocity after the last step with a positive
        force, and the velocity in the first state back at the surface (0 if it never leaves).
    """
    h = float(w0dt)
    gr = np.broadcast_to(np.asarray(gravity_ratio, float), np.shape(phases)).copy()
    u = -(1.0 + h * gr)
    y = np.asarray(phases, float) * h * u
    d = impedance
    release = np.full(y.shape, np.nan)
    surface = np.zeros(y.shape)
    released = np.zeros(y.shape, bool)
    done = np.zeros(y.shape, bool)
    for _ in range(int(t_max / h) + 100):
        aref = -(2.0 * zeta * u + y) / d
        force = (y < 0.0) & (aref > -gr)
        let_go = ~force & ~released
        release = np.where(let_go, u, release)
        released |= let_go
        u = u + h * np.where(force, d * aref + (1.0 - d) * -gr, -gr)
        y = y + h * u
        left = ~done & (y >= 0.0)
        surface = np.where(left, np.maximum(u, 0.0), surface)
        done |= left
        if done.all():
            break
    release = np.where(released, release, u)
    return release, surface


def _step_powers(m: np.ndarray, n: int) -> np.ndarray:
    """M^0 .. M^(n-1) of a 2 x 2 matrix, shape (n, 2, 2), by doubling (log2 n matmuls)."""
    p = np.empty((n, 2, 2))
    p[0] = np.eye(2)
    k = 1
    while k < n:
        mk = p[k - 1] @ m
        j = min(k, n - k)
        p[k : k + j] = p[:j] @ mk
        k += j
    return p


def impact_fast(
    zeta: float,
    w0dt: float,
    phases: np.ndarray,
    gravity_ratio: np.ndarray,
    impedance: float = IMPEDANCE,
) -> tuple[np.ndarray, np.ndarray]:
    """The result of :func:`emulate_surface`, without stepping (same rounding level).

    While the constraint pushes, one step is affine in (dist, velocity), so the states of the
    force phase are powers of the step matrix; after the force lets go the ball flies freely
    and the first state at the surface follows from a quadratic. Columns whose force phase does
    not end within 3.6 / w0, or whose constraint would grip again on the way out (very low
    impact speed), are emulated step by step.
    """
    h = float(w0dt)
    ph = np.asarray(phases, float)
    gr = np.broadcast_to(np.asarray(gravity_ratio, float), ph.shape)
    d = impedance
    b = 2.0 * zeta
    u0 = -(1.0 + h * gr)
    x0 = np.stack([ph * h * u0, u0])  # (2, n): dist, velocity
    m = np.array([[1.0 - h * h, h * (1.0 - b * h)], [-h, 1.0 - b * h]])
    c = -(1.0 - d) * h * np.stack([h * gr, gr])  # (2, n)
    fixed = np.linalg.solve(np.eye(2) - m, c)
    n = int(3.6 / h) + 3
    x = np.einsum("kij,jn->kin", _step_powers(m, n), x0 - fixed) + fixed[None]
    y, u = x[:, 0], x[:, 1]
    force = (y < 0.0) & (-(b * u + y) / d > -gr)
    force[0] = True
    r = np.argmin(force, axis=0)
    cols = np.arange(ph.size)
    ok = ~force[r, cols]
    yr, ur = y[r, cols], u[r, cols]
    # free flight: u_k = ur - k h gr, y_k = yr + h k ur - h^2 gr k (k + 1) / 2; first y_k >= 0
    a2 = 0.5 * h * h * gr
    b2 = h * ur - a2
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(
            gr > 0.0,
            (b2 - np.sqrt(np.maximum(b2 * b2 + 4.0 * a2 * yr, 0.0))) / (2.0 * a2),
            -yr / (h * ur),
        )
    k = np.maximum(np.ceil(np.nan_to_num(k, nan=0.0, posinf=0.0, neginf=0.0)), 0.0)

    def dist(k: np.ndarray) -> np.ndarray:
        return yr + h * k * ur - a2 * k * (k + 1.0)

    k = np.where((k > 0.0) & (dist(k - 1.0) >= 0.0), k - 1.0, k)
    k = np.where(dist(k) < 0.0, k + 1.0, k)
    # the constraint stays off on the way out if it is off at the last state inside (the
    # margin y + 2 zeta u - d gr is concave in k): otherwise step through it
    last = np.maximum(k - 1.0, 0.0)
    grip = (k > 0.0) & (dist(last) + b * (ur - last * h * gr) < d * gr)
    ok &= (ur > 0.0) & ~grip & (dist(k) >= 0.0)
    release, surface = ur, np.maximum(ur - k * h * gr, 0.0)
    if not ok.all():
        bad = ~ok
        release, surface = release.copy(), surface.copy()
        release[bad], surface[bad] = emulate_surface(zeta, h, ph[bad], gr[bad], impedance)
    return release, surface
