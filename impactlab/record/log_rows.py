"""What the recorder hands the log writer: a run's header, its rows, its impacts and outcome."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from pydantic import ValidationError

from impactlab.errors import SpecError
from impactlab.logs.checks import check_metadata, construction_problem
from impactlab.logs.format import OUTCOME_METADATA, RUN_METADATA
from impactlab.logs.metadata import Body, GeomContact, Outcome, PairTarget, RunMeta
from impactlab.logs.writer import LogHeader, LogRows
from impactlab.proto import impactlab_pb2 as pb
from impactlab.record import geometry
from impactlab.record.contacts import StepContacts
from impactlab.record.model import BODY_STATE_SIZE, InstrumentedModel
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
        Body(
            name=b.name,
            mass=b.mass,
            inertia=b.inertia,
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
        ground=tuple(inst.surfaces),
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
        inst.geoms,
        inst.xml,
        clearance,
        attachments=inst.attachments,
        meshes=inst.meshes,
        flexes=inst.flexes,
        contact_sides=contact_sides(inst),
        joint_energy=inst.joints is not None,
    )


def refuse_unreadable(inst: InstrumentedModel, info: RunInfo) -> None:
    """Raise SpecError when the log of this run would hold metadata its own reader refuses
    (a mass, size or energy beyond the log's declared ranges, a NaN): one contract, the
    log's (`impactlab.logs.metadata`: its models, and what their keys say of each other),
    checked before anything runs."""
    try:
        record = log_header(inst, info).run.record()
    except ValidationError as exc:
        problem = construction_problem(exc)
        raise SpecError(info.source, "", f"the log could not hold this run: {problem}") from None
    outcome = Outcome("completed", "", 1).record()
    problems = check_metadata({RUN_METADATA: record, OUTCOME_METADATA: outcome}).problems
    if problems:
        key, problem = next(iter(problems.items()))
        raise SpecError(info.source, "", f"the log could not hold this run: {key}: {problem}")


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


def log_rows(
    inst: InstrumentedModel,
    t_ns: np.ndarray,
    sensordata: np.ndarray,
    work: np.ndarray,
    contacts: StepContacts,
) -> LogRows:
    """The log's arrays for logged rows of sensordata (n, nsensordata), the work done
    before each (n, kinds) and the contacts at those rows (`step`: the row)."""
    adr = np.array([b.adr for b in inst.bodies], np.int64).reshape(-1, 1)
    bodies = sensordata[:, adr + np.arange(BODY_STATE_SIZE)]  # (n, nbody, 13)
    e = sensordata[:, inst.energy_adr : inst.energy_adr + 2]  # potential, kinetic
    energy = np.stack([e[:, 1], e[:, 0], e[:, 0] + e[:, 1]], axis=1)
    channels = [inst.clearance_of(b.name) for b in inst.bodies]
    columns = [c.adrs for body in channels for c in body]
    clearance = np.empty((len(t_ns), 0))
    if columns:  # each channel the min of its sensors, every channel at once
        starts = np.cumsum([0] + [len(c) for c in columns[:-1]])
        clearance = np.minimum.reduceat(sensordata[:, np.concatenate(columns)], starts, axis=1)
    joints = None
    if inst.joints is not None:  # the last two columns (`impactlab.record.simulate`)
        rotor, spring = sensordata[:, -2], sensordata[:, -1]
        joints = np.stack([rotor, spring, rotor + spring], axis=1)
    geoms = np.stack([contacts.geom1, contacts.geom2], axis=1)
    sides = np.where(geoms >= 0, geoms, -1 - np.stack([contacts.flex1, contacts.flex2], axis=1))
    normal, t1, t2 = contacts.frame[:, 0:3], contacts.frame[:, 3:6], contacts.frame[:, 6:9]
    f = contacts.force
    world = f[:, :1] * normal + f[:, 1:2] * t1 + f[:, 2:3] * t2
    points = np.hstack([contacts.pos, normal, contacts.penetration[:, None], f, world])
    return LogRows(
        t_ns,
        bodies,
        energy,
        work,
        (contacts.step, sides, points),
        clearance,
        joints,
    )


def contact_sides(inst: InstrumentedModel) -> dict[str, list[str]]:
    """What a logged contact point's sides refer to (`LogHeader.contact_sides`)."""
    model = inst.model
    ngeom = int(model.ngeom)
    return {
        "geoms": [model.geom(g).name for g in range(ngeom)],
        "bodies": [inst.party_names[int(inst.party[g])] for g in range(ngeom)],
        "flexes": list(inst.party_names[len(inst.party_names) - int(model.nflex) :]),
    }


def impacts(inst: InstrumentedModel, ending: Ending, timestep_ns: int) -> list[pb.Impact]:
    """The run's contact episodes as the log keeps them (`impactlab.Impact`)."""
    nbody, ngeom = len(inst.bodies), int(inst.model.ngeom)
    names = inst.party_names

    def kind(party: int) -> str:
        return "body" if party < nbody else "surface" if party < nbody + ngeom else "flex"

    def side(geom: int, party: int) -> str:
        return inst.model.geom(geom).name if geom >= 0 else names[party]

    def state(values: np.ndarray) -> pb.SideState:
        return pb.SideState(values=[] if np.isnan(values).any() else values.tolist())

    out = []
    for ep in ending.episodes:
        out.append(
            pb.Impact(
                side1=names[ep.side1],
                kind1=kind(ep.side1),
                side2=names[ep.side2],
                kind2=kind(ep.side2),
                geom1=side(ep.geom1, ep.side1),
                geom2=side(ep.geom2, ep.side2),
                onset_ns=ep.onset * timestep_ns,
                release_ns=(ep.last + (0 if ep.open else 1)) * timestep_ns,
                v_in=ep.v_in,
                v_out=ep.v_out,
                work_compression=ep.work_c,
                work_restitution=ep.work_r,
                work_friction=ep.work_f,
                peak_force=ep.peak_force,
                impulse=ep.impulse,
                max_penetration=ep.max_penetration,
                steps=ep.steps,
                open=ep.open,
                point_in=ep.point_in.tolist(),
                normal_in=ep.normal_in.tolist(),
                point_out=ep.point_out.tolist(),
                normal_out=ep.normal_out.tolist(),
                side1_in=state(ep.state_in[0]),
                side2_in=state(ep.state_in[1]),
                side1_out=state(ep.state_out[0]),
                side2_out=state(ep.state_out[1]),
            )
        )
    return out


def outcome(ending: Ending) -> Outcome:
    """How the run ended, for the log."""
    v = ending.verdict
    return Outcome(v.outcome, v.reason, ending.steps, tuple(ending.warnings))
