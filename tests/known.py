"""Known-answer runs, shared by the analysis tests and the analyze command's: a ball tossed
onto the ground and two balls meeting head on, both with MuJoCo's direct-form contact,
solref = (-k, -b) with k = 1e5 1/s^2 and b = 2 zeta sqrt(k), zeta = 0.1, and constant
impedance 0.9999: a linear spring-dashpot whose restitution is the Schwager-Poeschel closed
form, e = 0.7441 at zeta = 0.1."""

from __future__ import annotations

import math

from specs import DIRECT, collision, drop, toml

K = 1.0e5  # 1/s^2
ZETA = 0.1
DT = 1.0e-4  # s
G = 9.81  # m/s^2
RADIUS = 0.05  # m
Z0 = 1.05  # centre height: 1.0 m above the contact height
VX0, VZ0 = 0.3, 0.5  # a toss: up and sideways, so the free flight has v0 != 0
M1, M2, V1, V2 = 1.0, 2.0, 2.0, -1.0  # the collision's masses (kg) and speeds (m/s)
CONTACT = {**DIRECT, "solref": [-K, -2 * ZETA * math.sqrt(K)]}

DROP_SPEC = toml(
    drop(
        "known_drop",
        z=Z0,
        radius=RADIUS,
        vel=[VX0, 0.0, VZ0],
        timestep=DT,
        integrator="Euler",
        gravity=[0.0, 0.0, -G],
        contact=CONTACT,
        max_time=3.0,
        bounces=3,
    )
)
COLLISION_SPEC = toml(
    collision(
        "known_collision",
        names=("ball1", "ball2"),
        x=0.2,
        vel=(V1, V2),
        masses=(M1, M2),
        radius=RADIUS,
        timestep=DT,
        integrator="Euler",
        contact=CONTACT,
        max_time=1.0,
    )
)


def schwager_poeschel(zeta: float) -> float:
    """e of the linear dashpot with the contact ending at zero force (independent of k)."""
    w0 = 1.0
    beta = zeta * w0
    w = math.sqrt(w0**2 - beta**2)
    if beta < w0 / math.sqrt(2):
        return math.exp(-(beta / w) * (math.pi - math.atan(2 * beta * w / (w**2 - beta**2))))
    return math.exp(-(beta / w) * math.atan(2 * beta * w / (beta**2 - w**2)))
