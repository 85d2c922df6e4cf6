"""What the recorder hands the log writer: a run's header, its rows and its outcome.

The recorder's sensors (`impactlab.record.model`) put everything in MuJoCo's sensordata;
this module cuts those rows into the log's arrays (`impactlab.logs.writer.LogRows`) and
describes the run (`LogHeader`, `Outcome`) from the compiled model and the planned run.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from impactlab.logs.content import BodyMeta, LogHeader, LogRows, Outcome, RunMeta
from impactlab.logs.contract import GeomContact, PairTarget
from impactlab.logs.messages import POINT_FIELDS
from impactlab.record import geometry
from impactlab.record.model import (
    BODY_STATE_SIZE,
    CONTACT_SLOT_SIZE,
    ContactChannel,
    InstrumentedModel,
)
from impactlab.record.simulate import Ending


@dataclass(frozen=True)
class RunInfo:
    """What the metadata record says about a run besides its model and trajectory.

    `contact_targets`: the calibrated pairs' targets (as planned); `separation_m`: the
    separation stop rule (a collision), None without one.
    """

    run_id: str
    experiment: str
    description: str
    source: str
    spec: Mapping[str, Any]
    sweep: Mapping[str, Any]
    spec_hash: str
    log_every: int
    sweep_index: int = 0
    sweep_size: int = 1
    contact_targets: tuple[PairTarget, ...] = ()
    separation_m: float | None = None


def log_header(inst: InstrumentedModel, info: RunInfo) -> LogHeader:
    """The log's run metadata, pairs, scene and model text for one run."""
    model = inst.model
    bodies = [
        BodyMeta(
            name=b.name,
            mass=float(model.body_mass[b.body_id]),
            inertia=_xyz(model.body_inertia[b.body_id]),
            radius=b.radius,
            shape=b.shape,
            rest_height_m=b.rest_height,
            geoms=b.geoms,
            motion=b.motion,
        )
        for b in inst.bodies
    ]
    plane = [g for g in inst.geoms if g.type == "plane" and g.model_body == "world"]
    run = RunMeta(
        experiment=info.experiment,
        description=info.description,
        source=info.source,
        run_id=info.run_id,
        spec=info.spec,
        sweep=info.sweep,
        spec_hash=info.spec_hash,
        timestep_s=float(model.opt.timestep),
        log_every=info.log_every,
        gravity=_xyz(geometry.gravity(model)),
        bodies=bodies,
        plane_z=plane[0].pos[2] if plane else None,
        mujoco_version=mujoco.__version__,
        sweep_index=info.sweep_index,
        sweep_size=info.sweep_size,
        integrator=integrator_name(model),
        surfaces=inst.surfaces,
        static_potential_J=inst.static_potential,
        contact_targets=info.contact_targets,
        geom_contact=shared_geom_contact(model),
        separation_m=info.separation_m,
    )
    clearance = [
        (b.name, tuple(c.other for c in inst.clearance_of(b.name)))
        for b in inst.bodies
        if inst.clearance_of(b.name)
    ]
    return LogHeader(
        run,
        [c.meta for c in inst.contacts],
        inst.geoms,
        inst.xml,
        clearance,
        attachments=inst.attachments,
        meshes=inst.meshes,
        joint_energy=inst.joints is not None,
    )


def shared_geom_contact(model: mujoco.MjModel) -> GeomContact | None:
    """The solref and solimp every geom of the model has (None: they differ)."""
    solref, solimp = model.geom_solref, model.geom_solimp
    if not model.ngeom or (solref != solref[0]).any() or (solimp != solimp[0]).any():
        return None
    return GeomContact(tuple(map(float, solref[0])), tuple(map(float, solimp[0])))


def _xyz(values: np.ndarray) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in values)
    return x, y, z


def integrator_name(model: mujoco.MjModel) -> str:
    """The model's integrator as MJCF spells it (Euler, RK4, implicit, implicitfast)."""
    name: str = mujoco.mjtIntegrator(int(model.opt.integrator)).name.removeprefix("mjINT_")
    return {"EULER": "Euler", "RK4": "RK4"}.get(name, name.lower())


def log_rows(inst: InstrumentedModel, t_ns: np.ndarray, sensordata: np.ndarray) -> LogRows:
    """The log's arrays for rows of the recorder's sensordata, (n, nsensordata)."""
    n = sensordata.shape[0]
    bodies = np.stack(
        [sensordata[:, b.adr : b.adr + BODY_STATE_SIZE] for b in inst.bodies], axis=1
    ).reshape(n, len(inst.bodies), BODY_STATE_SIZE)
    e = sensordata[:, inst.energy_adr : inst.energy_adr + 2]  # potential, kinetic
    energy = np.stack([e[:, 1], e[:, 0], e[:, 0] + e[:, 1]], axis=1)
    contacts = [contact_points(pair, sensordata) for pair in inst.contacts]
    clearance = [
        np.stack([sensordata[:, list(c.adrs)].min(axis=1) for c in inst.clearance_of(b.name)], 1)
        for b in inst.bodies
        if inst.clearance_of(b.name)
    ]
    joints = None
    if inst.joints is not None:  # the last two columns (`impactlab.record.simulate`)
        rotor, spring = sensordata[:, -2], sensordata[:, -1]
        joints = np.stack([rotor, spring, rotor + spring], axis=1)
    return LogRows(t_ns, bodies, energy, contacts, clearance, joints)


def contact_points(pair: ContactChannel, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A contact sensor's slots -> (points per row (n,), points (n, num, 13) as POINT_FIELDS).

    Rows without contact have zero points (the writer logs no message for them).
    """
    slots = rows[:, pair.adr : pair.adr + pair.num * CONTACT_SLOT_SIZE]
    slots = slots.reshape(rows.shape[0], pair.num, CONTACT_SLOT_SIZE)
    count = np.minimum(slots[:, 0, 0], pair.num).astype(np.int64)
    points = np.zeros((rows.shape[0], pair.num, len(POINT_FIELDS)))
    touching = np.flatnonzero(count > 0)
    slots = slots[touching]
    force, dist, pos = slots[..., 1:4], slots[..., 4], slots[..., 5:8]
    normal, t1 = slots[..., 8:11], slots[..., 11:14]
    t2 = np.cross(normal, t1)
    world = force[..., 0:1] * normal + force[..., 1:2] * t1 + force[..., 2:3] * t2
    points[touching] = np.concatenate([pos, normal, -dist[..., None], force, world], axis=2)
    return count, points


def contact_work(ending: Ending, timestep_ns: int) -> list[np.ndarray]:
    """Each pair's contacts as the log writer takes them: steps turned into times (ns)."""
    out = []
    for work in ending.contact_work:
        work = work.copy()
        work[:, :2] *= timestep_ns
        out.append(work)
    return out


def outcome(ending: Ending) -> Outcome:
    """How the run ended, for the log."""
    v = ending.verdict
    return Outcome(v.outcome, v.reason, ending.steps, tuple(ending.warnings))
