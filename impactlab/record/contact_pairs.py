"""Calibrated contacts of a spec's pairs with a target restitution (docs/contact-model.md)."""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass

import numpy as np

from impactlab.contact import (
    RESTITUTION_TOLERANCE,
    SPEED_FLOOR_MPS,
    ContactModelError,
    ContactParams,
    CurveOutOfReach,
    RestitutionCurve,
    contact_params,
)
from impactlab.errors import SpecError
from impactlab.logs.checks import PLANE_GEOM
from impactlab.record.schema import ContactTarget
from impactlab.record.spec import Body, RunSpec, Stop


@dataclass(frozen=True)
class CalibratedPair:
    """Calibrated contact of one geom pair (geom names as in the model)."""

    geom1: str
    geom2: str
    params: ContactParams


def calibrated_pairs(run: RunSpec) -> list[CalibratedPair]:
    """Calibrated parameters for every pair with a target restitution (empty when none).

    Raises:
        SpecError: the target cannot be reached, the impact speeds cannot be derived, or the
            timestep does not resolve the contact.
    """
    con = run.contact
    g_down = max(-float(run.options.gravity[2]), 0.0)  # the plane's normal is +z
    out = []
    candidates: list[tuple[str, Body, Body | None]] = []
    if run.plane.enabled:
        candidates += [(PLANE_GEOM, b, None) for b in run.bodies]
    candidates += [(a.name, b, a) for a, b in itertools.combinations(run.bodies, 2)]
    for geom1, body, other in candidates:
        key = "/".join(sorted((geom1, body.name)))
        own = con.pairs.get(key, ContactTarget())
        e = con.restitution if own.restitution is None else own.restitution
        if e is None:
            if key in con.pairs:
                raise SpecError(
                    run.source,
                    f"contact.pairs.{key}",
                    "no restitution for this pair (give it here or in [contact])",
                )
            continue
        where = f"contact.pairs.{key}" if key in con.pairs else "contact"
        field = f"{where}.restitution" if own.restitution is not None else "contact.restitution"
        target_field = field
        if other is None:
            radius, g_normal, speed = body.radius, g_down, _plane_impact(body, g_down)
        else:  # two free balls fall together: gravity does not press them into each other
            radius, g_normal, speed = min(body.radius, other.radius), 0.0, _closing(other, body)
        speeds = con.speed_range if own.speed_range is None else own.speed_range
        if speeds is not None:
            field = f"{where}.speed_range" if own.speed_range is not None else "contact.speed_range"
        elif not speed > 0:
            raise SpecError(
                run.source,
                field,
                f"the bodies of {key} do not approach; set contact.speed_range "
                f'(or contact.pairs."{key}".speed_range)',
            )
        else:
            speeds = default_speed_range(speed, e, g_normal, run.stop, body)
        stiffness = own if own.duration is not None or own.max_penetration is not None else con
        # a curve's duration holds at one impact speed (none given: the designer's choice)
        at_speed = {"reference_speed_mps": stiffness.duration_speed}
        try:
            params = _calibrated(
                e,
                radius_m=radius,
                speed_range_mps=tuple(speeds),
                timestep_s=run.options.timestep,
                integrator=run.options.integrator,
                duration_s=stiffness.duration,
                max_penetration_m=stiffness.max_penetration,
                gravity_mps2=g_normal,
                allow_coarse=con.allow_coarse_timestep,
                **(at_speed if stiffness.duration_speed is not None else {}),
            )
        except CurveOutOfReach as exc:  # the curve is what cannot be followed
            raise SpecError(run.source, target_field, str(exc)) from None
        except ContactModelError as exc:
            raise SpecError(run.source, field, str(exc)) from None
        out.append(CalibratedPair(geom1, body.name, params))
    return out


_calibrated = functools.lru_cache(maxsize=1024)(contact_params)
"""`contact_params` once per process for the same arguments: a run's pairs are calibrated when
it is planned, again when the recorder reads the plan and when its model is built (in a forked
worker, which inherits what the parent calibrated)."""


def default_speed_range(
    first_mps: float, e: float | RestitutionCurve, g_normal: float, stop: Stop, body: Body
) -> tuple[float, float]:
    """The impact speeds (m/s) a pair's contact must hold e over, from the experiment
    (docs/contact-model.md): `first_mps` the first impact speed, `g_normal` gravity along
    the contact normal (0: one impact). A curve promises no e below its slowest point: the
    range stops there (each bounce taken at the curve's highest e, the slowest it gets)."""
    if g_normal <= 0.0:
        return first_mps, first_mps
    if isinstance(e, RestitutionCurve):
        low, high = default_speed_range(first_mps, max(e.e), g_normal, stop, body)
        return min(max(low, e.span_mps[0]), high), high
    decay = max(e - RESTITUTION_TOLERANCE, 0.0)
    height = max(body.pos[2] - body.radius, 0.0)
    vz = body.vel[2]
    t = (vz + math.sqrt(vz * vz + 2.0 * g_normal * height)) / g_normal  # first impact
    v, n = first_mps, 1
    bounces = stop.bounces if stop.bounces is not None else math.inf
    while n < bounces and v > SPEED_FLOOR_MPS:
        t += 2.0 * v * decay / g_normal  # the flight to the next impact, at its speed
        if t > stop.max_time:
            break
        v, n = v * decay, n + 1
    return min(max(v, SPEED_FLOOR_MPS), first_mps), first_mps


def _plane_impact(body: Body, g_down: float) -> float:
    """Impact speed (m/s) of a ball falling on the plane z = 0 (`g_down`: gravity along -z)."""
    height = max(body.pos[2] - body.radius, 0.0)
    vz = body.vel[2]
    if g_down == 0.0:
        return max(-vz, 0.0)
    return math.sqrt(vz * vz + 2.0 * g_down * height)  # energy: up, then down


def _closing(a: Body, b: Body) -> float:
    """Closing speed (m/s) of two balls along their line of centres."""
    d = np.subtract(b.pos, a.pos)
    return float(np.dot(np.subtract(a.vel, b.vel), d / np.linalg.norm(d)))
