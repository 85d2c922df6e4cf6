"""Per-pair contacts of a spec whose contact asks for a coefficient of restitution.

Each ball-plane and ball-ball pair with a target e gets calibrated MuJoCo parameters
(`impactlab.contact`) at a design impact speed: the spec's `contact.impact_speed`,
or else the speed the initial state gives (fall height under gravity, or closing speed).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from impactlab.contact import ContactModelError, ContactParams, contact_params
from impactlab.errors import SpecError
from impactlab.record.spec import Body, RunSpec

PLANE_GEOM = "plane"


@dataclass(frozen=True)
class PairContact:
    """Calibrated contact of one geom pair (geom names as in the model)."""

    geom1: str
    geom2: str
    params: ContactParams


def calibrated_pairs(run: RunSpec) -> list[PairContact]:
    """Calibrated parameters for every pair with a target restitution (empty when none).

    Raises:
        SpecError: a pair names an unknown geom, the target cannot be reached, the impact
            speed cannot be derived, or the timestep does not resolve the contact.
    """
    con = run.contact
    per_pair = dict(con.pair_restitution or {})
    geoms = {b.name for b in run.bodies} | ({PLANE_GEOM} if run.plane.enabled else set())
    for key in per_pair:
        unknown = [g for g in key.split("/") if g not in geoms]
        if unknown:
            raise SpecError(
                run.source,
                f"contact.pairs.{key}",
                f"no geom named {unknown[0]!r} ({sorted(geoms)})",
            )
    g = np.asarray(run.options.gravity)
    out = []
    candidates: list[tuple[str, Body, Body | None]] = []
    if run.plane.enabled:
        candidates += [(PLANE_GEOM, b, None) for b in run.bodies]
    candidates += [(a.name, b, a) for a, b in itertools.combinations(run.bodies, 2)]
    for geom1, body, other in candidates:
        key = "/".join(sorted((geom1, body.name)))
        e = per_pair.get(key, con.restitution)
        if e is None:
            continue
        field = f"contact.pairs.{key}" if key in per_pair else "contact.restitution"
        if other is None:
            radius, (speed, g_normal) = body.radius, _plane_impact(body, g)
        else:
            radius = min(body.radius, other.radius)
            speed, g_normal = _closing_speed(other, body, g)
        if con.impact_speed is not None:
            speed = con.impact_speed
        if not speed > 0:
            raise SpecError(
                run.source, field, f"the bodies of {key} do not approach; set contact.impact_speed"
            )
        try:
            params = contact_params(
                e,
                radius_m=radius,
                impact_speed_mps=speed,
                timestep_s=run.options.timestep,
                duration_s=con.duration,
                max_penetration_m=con.max_penetration,
                gravity_mps2=g_normal,
                allow_coarse=con.allow_coarse_timestep,
            )
        except ContactModelError as exc:
            raise SpecError(run.source, field, str(exc)) from None
        out.append(PairContact(geom1, body.name, params))
    return out


def _plane_impact(body: Body, g: np.ndarray) -> tuple[float, float]:
    """Impact speed (m/s) of a ball falling on the plane z = 0, and gravity along the normal."""
    g_down = max(-float(g[2]), 0.0)
    height = max(body.pos[2] - body.radius, 0.0)
    vz = body.vel[2]
    if g_down == 0.0:
        return max(-vz, 0.0), 0.0
    return math.sqrt(vz * vz + 2.0 * g_down * height), g_down  # energy: up, then down


def _closing_speed(a: Body, b: Body, g: np.ndarray) -> tuple[float, float]:
    """Closing speed (m/s) of two balls along their line of centres, and the relative gravity.

    Two free balls fall together: gravity gives them no relative acceleration, so the
    contact sees none (0).
    """
    d = np.subtract(b.pos, a.pos)
    n = d / np.linalg.norm(d)
    closing = float(np.dot(np.subtract(a.vel, b.vel), n))
    return closing, 0.0
