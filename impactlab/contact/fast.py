"""Gravity's effect on e without stepping through the contact: the force phase in closed form."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from impactlab.contact.emulation import (
    IMPEDANCE,
    emulate_surface,
    free_step_travel,
    scheme_of,
    speed_in,
    step,
)

_RELEASE_STEPS = 6
"""Steps stepped one by one after the force phase, until every stage of a step is free."""


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


def _matrices(h: float, b: float, scheme: str) -> tuple[np.ndarray, list[np.ndarray]]:
    """The force phase's step matrix about its fixed point, and its stage matrices.

    With the force on, (dist, velocity)' = J (x - x*), J = [[0, 1], [-1, -b]].
    """
    if scheme == "euler":
        m = np.array([[1.0 - h * h, h * (1.0 - b * h)], [-h, 1.0 - b * h]])
        return m, [np.eye(2)]
    hj = h * np.array([[0.0, 1.0], [-1.0, -b]])
    i = np.eye(2)
    hj2 = hj @ hj
    hj3 = hj2 @ hj
    m = i + hj + hj2 / 2.0 + hj3 / 6.0 + hj3 @ hj / 24.0
    return m, [i, i + hj / 2.0, i + hj / 2.0 + hj2 / 4.0, i + hj + hj2 / 2.0 + hj3 / 4.0]


def impact_fast(
    zeta: float,
    w0dt: float,
    phases: np.ndarray,
    gravity_ratio: np.ndarray,
    integrator: str = "Euler",
) -> tuple[np.ndarray, np.ndarray]:
    """(release, surface) of :func:`emulation.emulate_surface`, without stepping the contact.

    Args:
        zeta: damping ratio.
        w0dt: w0 * timestep.
        phases: contact-onset phases in (0, 1], shape (n,).
        gravity_ratio: g / (w0 v_in), scalar or shape (n,).
        integrator: MuJoCo's integrator name.

    Returns:
        (release, surface), each shape (n,), equal to the emulation's to rounding.
    """
    scheme = scheme_of(integrator)
    h, d, b = float(w0dt), IMPEDANCE, 2.0 * zeta
    ph = np.asarray(phases, float)
    gr = np.broadcast_to(np.asarray(gravity_ratio, float), ph.shape).copy()
    y0 = (1.0 - ph) * free_step_travel(h, gr, scheme)
    u0 = -np.ones(ph.shape)
    # the onset step (free, or with force at some stages), then the force phase in closed form
    ys, us, _ = step(y0, u0, h, b, gr, scheme)
    fixed = np.stack([-(1.0 - d) * gr, np.zeros(ph.shape)])  # (2, n)
    m, stages = _matrices(h, b, scheme)
    n = int(3.6 / h) + 3
    rel = np.einsum("kij,jn->kin", _step_powers(m, n), np.stack([ys, us]) - fixed)
    pushes = np.ones((n, ph.size), bool)
    for s in stages:
        x = np.einsum("ij,kjn->kin", s, rel) + fixed[None]
        pushes &= (x[:, 0] < 0.0) & (b * x[:, 1] + x[:, 0] < d * gr)
    ok = pushes[0] & ~pushes.all(axis=0)
    r = np.argmin(pushes, axis=0)
    cols = np.arange(ph.size)
    x_r = rel[r, :, cols].T + fixed  # (2, n): the first state whose step is not all force
    y, u = x_r[0].copy(), x_r[1].copy()
    release = u.copy()
    done = y >= 0.0  # back at the surface (the force pushed until then)
    surface = np.where(done, np.maximum(u, 0.0), 0.0)
    flying = np.zeros(ph.shape, bool)  # a step with no force: free flight from (y, u)
    released = np.zeros(ph.shape, bool)
    for _ in range(_RELEASE_STEPS):
        active = ~done & ~flying
        y1, u1, any_force = step(y, u, h, b, gr, scheme)
        released |= active & ~any_force
        release = np.where(active & any_force & ~released, u1, release)
        y, u = np.where(active, y1, y), np.where(active, u1, u)
        back = active & (y >= 0.0)
        surface = np.where(back, np.maximum(u, 0.0), surface)
        done |= back
        flying |= active & ~back & ~any_force & (u > 0.0)
        if (done | flying).all():
            break
    ok &= done | flying
    # free flight from (y, u): u_k = u - k h gr; first k >= 1 with y_k >= 0
    a2 = 0.5 * h * h * gr
    b2 = h * u - a2 if scheme == "euler" else h * u
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(
            gr > 0.0,
            (b2 - np.sqrt(np.maximum(b2 * b2 + 4.0 * a2 * y, 0.0))) / (2.0 * a2),
            -y / (h * u),
        )
    k = np.maximum(np.ceil(np.nan_to_num(k, nan=0.0, posinf=0.0, neginf=0.0)), 1.0)

    def dist(k: np.ndarray) -> np.ndarray:
        kk = k * (k + 1.0) if scheme == "euler" else k * k
        y_k: np.ndarray = y + h * k * u - a2 * kk
        return y_k

    k = np.where((k > 1.0) & (dist(k - 1.0) >= 0.0), k - 1.0, k)
    k = np.where(dist(k) < 0.0, k + 1.0, k)
    # the constraint stays off on the way out if it is off at every stage of the last step
    # inside (the margin dist + 2 zeta u - d gr is concave along the flight)
    last_y, last_u = dist(k - 1.0), u - (k - 1.0) * h * gr
    _, _, grips = step(last_y, last_u, h, b, gr, scheme)
    u_out = u - k * h * gr
    ok &= ~flying | (~grips & (dist(k) >= 0.0) & (u_out >= 0.0))
    surface = np.where(flying, np.maximum(u_out, 0.0), surface)
    if not ok.all():
        bad = ~ok
        release, surface = release.copy(), surface.copy()
        r_bad, s_bad, _ = emulate_surface(zeta, h, ph[bad], gr[bad], integrator=integrator)
        release[bad], surface[bad] = r_bad, s_bad
    return release, surface


_SHIFT_PHASES = (np.arange(16) + 0.5) / 16


_SHIFT_W0DT_MIN = 0.01


def gravity_shift(
    zeta: float,
    w0dt: float,
    gravity_ratio: Sequence[float] | np.ndarray,
    integrator: str = "Euler",
) -> np.ndarray:
    """Gravity's change of e at impact speeds (mean over phases), one per ratio.

    ``mean(e at g / (w0 v)) - mean(e at zero gravity)`` by :func:`impact_fast` over 16
    contact-onset phases, e = -v_out / v_in as the recorder measures them; about
    -2 zeta g / (w0 v). Steps finer than w0 dt = 0.01 are evaluated at 0.01 (the shift
    changes by O(w0 dt g / (w0 v)), below 1e-4 there).

    Args:
        zeta: damping ratio.
        w0dt: w0 * timestep.
        gravity_ratio: g / (w0 v), one per impact speed.
        integrator: MuJoCo's integrator name.
    """
    ratios = np.atleast_1d(np.asarray(gravity_ratio, float))
    h = max(float(w0dt), _SHIFT_W0DT_MIN)
    n = _SHIFT_PHASES.size
    gr = np.concatenate([np.zeros(n), np.repeat(np.maximum(ratios, 0.0), n)])
    phases = np.tile(_SHIFT_PHASES, ratios.size + 1)
    _, surface = impact_fast(zeta, h, phases, gr, integrator=integrator)
    e = surface / speed_in(h, gr, scheme_of(integrator))
    means = e.reshape(ratios.size + 1, n).mean(axis=1)
    shift: np.ndarray = np.where(ratios > 0.0, means[1:] - means[0], 0.0)
    return shift
