"""One impact measured in plain MuJoCo (`mj_step`), e as the recorder defines it: the tests'
oracle for the contact designer, independent of impactlab's recorder.

v_in is the normal velocity before any contact force acted: in the first state in contact,
for RK4 in the state before (the later stages of its step meet the surface already); v_out in
the first state out of contact after it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from impactlab.contact import ContactModelError, ContactParams


@dataclass(frozen=True)
class ImpactMeasurement:
    """One impact measured in MuJoCo (normal components; ball 1 moves towards ball 2 / floor).

    Attributes:
        restitution: -(relative normal velocity after) / (relative normal velocity before).
        v_before_mps: body velocities (z for the floor, x for two balls) before any contact
            force acted (see the module docstring), shape (nbody,).
        v_after_mps: body velocities in the first state after the overlap, (nbody,).
        max_penetration_m: largest overlap in m.
        steps_in_contact: number of steps with a positive contact force.
    """

    restitution: float
    v_before_mps: tuple[float, ...]
    v_after_mps: tuple[float, ...]
    max_penetration_m: float
    steps_in_contact: int


def ball_plane_mjcf(
    params: ContactParams, *, radius_m: float, mass_kg: float, gravity_mps2: float
) -> str:
    """Inline MJCF: a frictionless (condim 1) ball on a plane, the pair set by ``<pair>``."""
    a = params.mjcf_attributes()
    return f"""<mujoco><option timestep="{params.timestep_s!r}" integrator="{params.integrator}"
gravity="0 0 {-gravity_mps2!r}"/>
<worldbody><geom name="floor" type="plane" size="10 10 1" condim="1"/>
<body name="ball" pos="0 0 1"><freejoint/>
<geom name="ball" type="sphere" size="{radius_m!r}" mass="{mass_kg!r}" condim="1"/></body>
</worldbody><contact><pair geom1="floor" geom2="ball" condim="1" solref="{a["solref"]}"
solimp="{a["solimp"]}"/></contact></mujoco>"""


def ball_ball_mjcf(
    params: ContactParams, *, radius_m: tuple[float, float], mass_kg: tuple[float, float]
) -> str:
    """Inline MJCF: two frictionless balls on the x axis in zero gravity, ``<pair>`` contact."""
    a = params.mjcf_attributes()
    return f"""<mujoco><option timestep="{params.timestep_s!r}" integrator="{params.integrator}"
gravity="0 0 0"/>
<worldbody>
<body name="b1" pos="-1 0 0"><freejoint/>
<geom name="b1" type="sphere" size="{radius_m[0]!r}" mass="{mass_kg[0]!r}" condim="1"/></body>
<body name="b2" pos="1 0 0"><freejoint/>
<geom name="b2" type="sphere" size="{radius_m[1]!r}" mass="{mass_kg[1]!r}" condim="1"/></body>
</worldbody><contact><pair geom1="b1" geom2="b2" condim="1" solref="{a["solref"]}"
solimp="{a["solimp"]}"/></contact></mujoco>"""


def _measure(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    velocities: Callable[[mujoco.MjData], np.ndarray],
    overlap: Callable[[mujoco.MjData], float],
    max_steps: int,
) -> ImpactMeasurement:
    """Step until the bodies overlap and part again; the velocities in and out (see the
    module docstring)."""
    rk4 = model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    v_prev: np.ndarray | None = None
    v_before: np.ndarray | None = None
    v_after: np.ndarray | None = None
    pen, steps = 0.0, 0
    for _ in range(max_steps):
        inside = overlap(data) > 0.0
        v_now = velocities(data)
        if inside:
            if v_before is None:
                if v_prev is None:
                    raise ContactModelError("the bodies overlap in the initial state")
                v_before = v_prev if rk4 else v_now
            pen = max(pen, overlap(data))
        elif v_before is not None:
            v_after = v_now
            break
        v_prev = v_now
        mujoco.mj_step(model, data)
        steps += data.nefc > 0 and bool(np.any(data.efc_force[: data.nefc] > 0.0))
    if v_before is None or v_after is None:
        raise ContactModelError("no complete contact within the simulated steps")
    rel_in = v_before[-1] - v_before[0]
    rel_out = v_after[-1] - v_after[0]
    return ImpactMeasurement(
        restitution=-rel_out / rel_in,
        v_before_mps=tuple(map(float, v_before)),
        v_after_mps=tuple(map(float, v_after)),
        max_penetration_m=pen,
        steps_in_contact=steps,
    )


def measure_ball_plane(
    params: ContactParams,
    *,
    radius_m: float,
    mass_kg: float,
    impact_speed_mps: float,
    gravity_mps2: float = 9.81,
    gap_m: float | None = None,
) -> ImpactMeasurement:
    """Drop a ball onto a plane in MuJoCo and measure e from the velocities around the contact.

    The ball starts ``gap_m`` above the plane (default 2.37 steps of travel) moving down at
    the speed that makes it arrive at ``impact_speed_mps``.
    """
    model = mujoco.MjModel.from_xml_string(
        ball_plane_mjcf(params, radius_m=radius_m, mass_kg=mass_kg, gravity_mps2=gravity_mps2)
    )
    data = mujoco.MjData(model)
    gap = 2.37 * impact_speed_mps * params.timestep_s if gap_m is None else gap_m
    data.qpos[2] = radius_m + gap
    data.qvel[2] = -math.sqrt(max(impact_speed_mps**2 - 2.0 * gravity_mps2 * gap, 0.0))
    max_steps = int(20.0 * params.duration_s / params.timestep_s) + 10 * int(
        gap / (impact_speed_mps * params.timestep_s) + 10
    )
    meas = _measure(
        model,
        data,
        lambda d: np.array([0.0, -d.qvel[2]]),  # (floor, ball) velocities towards the floor
        lambda d: radius_m - d.qpos[2],
        max_steps,
    )
    return ImpactMeasurement(
        restitution=meas.restitution,
        v_before_mps=(-meas.v_before_mps[1],),
        v_after_mps=(-meas.v_after_mps[1],),
        max_penetration_m=meas.max_penetration_m,
        steps_in_contact=meas.steps_in_contact,
    )


def measure_ball_ball(
    params: ContactParams,
    *,
    radius_m: tuple[float, float],
    mass_kg: tuple[float, float],
    velocity_mps: tuple[float, float],
    gap_m: float | None = None,
) -> ImpactMeasurement:
    """Collide two balls head-on along x in zero gravity and measure e and both velocities.

    Ball 1 (left) moves at velocity_mps[0], ball 2 (right) at velocity_mps[1] (closing speed
    v1 - v2 > 0); they start ``gap_m`` apart (default 2.37 steps of closing travel).
    """
    model = mujoco.MjModel.from_xml_string(
        ball_ball_mjcf(params, radius_m=radius_m, mass_kg=mass_kg)
    )
    data = mujoco.MjData(model)
    closing = velocity_mps[0] - velocity_mps[1]
    if not closing > 0.0:
        raise ContactModelError(f"balls must approach (v1 - v2 > 0), got {velocity_mps}")
    gap = 2.37 * closing * params.timestep_s if gap_m is None else gap_m
    data.qpos[0] = -radius_m[0] - gap / 2.0
    data.qpos[7] = radius_m[1] + gap / 2.0
    data.qvel[0], data.qvel[6] = velocity_mps
    max_steps = int(20.0 * params.duration_s / params.timestep_s) + int(
        10 * gap / (closing * params.timestep_s) + 100
    )
    meas = _measure(
        model,
        data,
        lambda d: np.array([d.qvel[6], d.qvel[0]]),  # ordered so that out/in is the closing rate
        lambda d: radius_m[0] + radius_m[1] - (d.qpos[7] - d.qpos[0]),
        max_steps,
    )
    return ImpactMeasurement(
        restitution=meas.restitution,
        v_before_mps=(meas.v_before_mps[1], meas.v_before_mps[0]),
        v_after_mps=(meas.v_after_mps[1], meas.v_after_mps[0]),
        max_penetration_m=meas.max_penetration_m,
        steps_in_contact=meas.steps_in_contact,
    )
