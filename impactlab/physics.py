"""Analytic formulas the measurements are compared against (numbers or polars expressions).

Free flight, apex heights and the 1D collision with restitution e; where the analysis uses
them: docs/analysis.md (and docs/contact-model.md for the contact itself).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal, TypeVar, get_args

if TYPE_CHECKING:
    import numpy as np
    import polars as pl

X = TypeVar("X")


def e_velocity(v_in: X, v_out: X) -> X:
    """The coefficient of restitution by velocity, -v_out / v_in: the contact points' normal
    velocities as the surfaces meet (v_in < 0) and part (numbers, arrays or expressions)."""
    return -v_out / v_in  # type: ignore[operator,no-any-return]


def e_energy(work_c: pl.Expr, work_r: pl.Expr, closed: pl.Expr) -> pl.Expr:
    """The energetic coefficient of restitution (Stronge), sqrt(W_r / -W_c): the normal
    force's work while the points separate over that while they approach; at most 1 for a
    contact that dissipates, whatever turns or drives the bodies. Null for a contact still
    open (`closed` false) or works of the wrong signs."""
    import polars as pl  # not at the top: the recorder imports this module without polars

    ok = closed & (work_c < 0) & (work_r >= 0)
    return pl.when(ok).then((work_r / -work_c).sqrt())


def collision_after(m1: X, m2: X, v1: X, v2: X, e: X | float) -> tuple[X, X]:
    """(v1', v2') of a 1D collision with restitution e: masses in kg, velocities in m/s along
    the line of centres (numbers, arrays or polars expressions)."""
    p = m1 * v1 + m2 * v2  # type: ignore[operator]
    total = m1 + m2  # type: ignore[operator]
    return (p + m2 * e * (v2 - v1)) / total, (p + m1 * e * (v1 - v2)) / total  # type: ignore[operator]


RK4 = "RK4"
SEMI_IMPLICIT = ("Euler", "implicit", "implicitfast")
"""MuJoCo's integrators that advance positions with the velocity after the step: in a free
flight under gravity g each step loses m g^2 dt^2 / 2, so a flight of T seconds loses
m g^2 dt T / 2 (checked with MuJoCo: all three give the same energy to 1e-15). RK4 follows
the parabola exactly and has no such drift."""
Integrator = Literal["Euler", "RK4", "implicit", "implicitfast"]
"""MuJoCo's integrators as MJCF spells them (the log's `integrator` key)."""
INTEGRATORS: tuple[str, ...] = get_args(Integrator)


def half_step_s(integrator: str, timestep_s: float) -> float:
    """How far, in s, the logged positions of a free flight lag the parabola of its velocities.

    MuJoCo's semi-implicit integrators advance the position with the velocity after the
    step, which puts the parabola through the logged positions half a step late: dt / 2.
    RK4 follows the parabola: 0.

    Raises:
        ValueError: `integrator` is not one of `INTEGRATORS`.
    """
    if integrator == RK4:
        return 0.0
    if integrator in SEMI_IMPLICIT:
        return timestep_s / 2
    raise ValueError(f"unknown integrator {integrator!r} (one of {', '.join(INTEGRATORS)})")


MIN_FLIGHT_STEPS = 10
"""Simulated steps two surfaces must stay apart for a contact to have ended: closer
contacts are one (a resting, sliding or rolling contact flickers in MuJoCo)."""


def min_impact_speed(gravity_mps2: float, timestep_s: float) -> float:
    """The slowest arrival (m/s) that is an impact: a body released against gravity at this
    speed flies `MIN_FLIGHT_STEPS` steps; slower arrivals are a contact at rest."""
    return 0.5 * MIN_FLIGHT_STEPS * abs(gravity_mps2) * timestep_s


def up_vector(gravity: np.ndarray) -> np.ndarray:
    """Unit vector against gravity, (3,); +z without gravity (or one no float holds)."""
    import numpy as np

    scale = float(np.abs(gravity).max())
    if not 0 < scale < np.inf:
        return np.array([0.0, 0.0, 1.0])
    g = gravity / scale  # a huge gravity (1e300) would overflow the norm to inf
    return -g / np.linalg.norm(g)


def restitution_on_curve(speed_mps: object, curve_speed_mps: object, curve_e: object) -> np.ndarray:
    """A target e(v) at normal impact speeds (m/s): piecewise linear in speed between the
    curve's points (ascending speeds), NaN outside them (no target is promised there)."""
    import numpy as np  # not at the top: the command line imports this module

    speeds = np.asarray(speed_mps, float)
    xs, es = np.asarray(curve_speed_mps, float), np.asarray(curve_e, float)
    inside = (speeds >= xs[0]) & (speeds <= xs[-1])
    return np.where(inside, np.interp(speeds, xs, es), np.nan)
