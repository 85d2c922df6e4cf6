"""Build MuJoCo models for recording: from an experiment spec, or any user MJCF, instrumented.

Instrumenting adds the sensors the recorder reads, so a batched `mujoco.rollout` captures
everything without a Python loop: per free body its pose and world-frame velocities, MuJoCo's
kinetic and potential energy, one `contact` sensor per pair of geoms that can touch, and one
`distance` sensor per pair of a body's collision geom and a ground surface (its clearance)
or another free body's geom (the gap the separation stop rule watches). The ground and the
bodies' shapes are described by `impactlab.record.geometry`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from impactlab.errors import SpecError
from impactlab.logs.content import PairMeta, SurfaceMeta
from impactlab.logs.scene import GeomShape
from impactlab.record import geometry
from impactlab.record.contact_pairs import CalibratedPair, calibrated_pairs
from impactlab.record.geoms import describe as describe_geoms
from impactlab.record.joint_energy import TENDON_SENSOR, JointEnergy, joint_energy, sprung_tendons
from impactlab.record.model_names import SENSOR_PREFIX as SENSOR_PREFIX  # the base prefix
from impactlab.record.model_names import name_unnamed, sensor_prefix
from impactlab.record.mujoco_version import require_mujoco  # noqa: F401 (checks at import)
from impactlab.record.spec import RunSpec

# contact sensor data fields: found, force, dist, pos, normal, tangent (mjtConDataField bits)
CONTACT_DATA_BITS = 1 | 2 | 8 | 16 | 32 | 64
CONTACT_SLOT_SIZE = 1 + 3 + 1 + 3 + 3 + 3
BODY_STATE_SIZE = 13  # pos 3, quat 4, linvel 3, angvel 3
PLANE_NAME = "plane"
DISTANCE_CUTOFF_M = 1.0e4
"""Distances beyond this are reported as this (MuJoCo's distance sensors need a cutoff)."""


@dataclass(frozen=True)
class BodyChannel:
    """A moving body, where its 13 state values start in sensordata, and its shape.

    The state is the body's centre of mass and inertial frame (MuJoCo's `xipos`, `ximat`)
    and their world-frame velocities.

    Attributes:
        radius: the radius when the body is one sphere centred at its centre of mass.
        shape: its collision geoms' types ("sphere", "box", "box+sphere", ...).
        rest_height: lowest centre-of-mass height above a flat surface it touches, m.
        geoms: names of its collision geoms.
        motion: "free" (a lone free body: ballistic between contacts) or "articulated".
    """

    name: str
    body_id: int
    adr: int
    radius: float | None
    shape: str = "sphere"
    rest_height: float | None = None
    geoms: tuple[str, ...] = ()
    motion: str = "free"


@dataclass(frozen=True)
class DistanceChannel:
    """A body's distance to a surface (or another body): the min of the sensors at `adrs`."""

    body: str
    other: str
    adrs: tuple[int, ...]


@dataclass(frozen=True)
class ContactChannel:
    """A geom pair and where its contact sensor's `num` slots start in sensordata."""

    geom1: str
    geom2: str
    body1: str
    body2: str
    adr: int
    num: int

    @property
    def meta(self) -> PairMeta:
        """The pair as the log describes it."""
        return PairMeta(self.geom1, self.geom2, self.body1, self.body2)


@dataclass
class InstrumentedModel:
    """A compiled model, its MJCF text and the layout of what the recorder reads."""

    model: mujoco.MjModel
    xml: str  # the MJCF text as written by impactlab or the user (full precision)
    bodies: list[BodyChannel]
    contacts: list[ContactChannel]
    geoms: list[GeomShape]
    energy_adr: int
    keyframe: int | None
    surfaces: list[SurfaceMeta] = field(default_factory=list)
    clearances: list[DistanceChannel] = field(default_factory=list)  # body to surface
    gaps: list[DistanceChannel] = field(default_factory=list)  # body to body
    static_potential: float = 0.0  # MuJoCo's potential energy of the static bodies, J
    joints: JointEnergy | None = None  # rotor inertia and springs, if the model has any
    attachments: tuple[tuple[str, str, bytes], ...] = ()  # more files for the log (name, type)
    inputs: tuple[tuple[str, str], ...] = ()  # (file, SHA-256) the model reads besides its own
    meshes: dict[str, np.ndarray] = field(default_factory=dict)  # triangles by attachment name

    def clearance_of(self, body: str) -> list[DistanceChannel]:
        """The body's distance channels to the ground surfaces, in surface order."""
        return [c for c in self.clearances if c.body == body]

    def initial_state(self) -> np.ndarray:
        """Full physics state at the start of the run (the `initial` keyframe if any), (nstate,)."""
        data = mujoco.MjData(self.model)
        if self.keyframe is None:
            mujoco.mj_resetData(self.model, data)
        else:
            mujoco.mj_resetDataKeyframe(self.model, data, self.keyframe)
        kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
        state = np.empty(mujoco.mj_stateSize(self.model, kind))
        mujoco.mj_getState(self.model, data, state, kind)
        return state


def mjcf_from_spec(run: RunSpec, pairs: Sequence[CalibratedPair] | None = None) -> str:
    """The MJCF text of a spec's model, with the handout's `<default><geom>` contact and a
    `<pair>` per calibrated pair (`pairs`, as planned; None: calibrated here)."""
    opt, con = run.options, run.contact
    lines = [
        f'<mujoco model="{run.experiment}">',
        f'  <option timestep="{opt.timestep!r}" integrator="{opt.integrator}" '
        f'gravity="{_fmt(opt.gravity)}"/>',
        "  <default>",
        f'    <geom condim="{con.condim}" solref="{_fmt(con.solref)}" solimp="{_fmt(con.solimp)}" '
        f'friction="{_fmt(con.friction)}"/>',
        "  </default>",
        "  <worldbody>",
    ]
    if run.plane.enabled:
        lines.append(
            f'    <geom name="{PLANE_NAME}" type="plane" size="{_fmt(run.plane.size)}" '
            f'rgba="{_fmt(run.plane.rgba)}"/>'
        )
    for b in run.bodies:
        lines += [
            f'    <body name="{b.name}" pos="{_fmt(b.pos)}">',
            f'      <freejoint name="{b.name}"/>',
            f'      <geom name="{b.name}" type="sphere" size="{b.radius!r}" mass="{b.mass!r}" '
            f'rgba="{_fmt(b.rgba)}"/>',
            "    </body>",
        ]
    lines.append("  </worldbody>")
    if pairs is None:
        pairs = calibrated_pairs(run)
    if pairs:
        lines.append("  <contact>")
        lines += [f"    {pair.params.mjcf_pair(pair.geom1, pair.geom2)}" for pair in pairs]
        lines.append("  </contact>")
    qpos = " ".join(_fmt((*b.pos, 1.0, 0.0, 0.0, 0.0)) for b in run.bodies)
    qvel = " ".join(_fmt((*b.vel, *b.angvel)) for b in run.bodies)
    lines += ["  <keyframe>", f'    <key name="initial" qpos="{qpos}" qvel="{qvel}"/>']
    lines += ["  </keyframe>", "</mujoco>", ""]
    return "\n".join(lines)


def _fmt(values: tuple[float, ...] | list[float]) -> str:
    return " ".join(repr(float(v)) for v in values)


def model_from_spec(
    run: RunSpec, pairs: Sequence[CalibratedPair] | None = None
) -> InstrumentedModel:
    """Compile a spec's model with the recorder's sensors (`pairs`: as `mjcf_from_spec`)."""
    xml = mjcf_from_spec(run, pairs)
    return instrument(mujoco.MjSpec.from_string(xml), run.source, xml=xml, keyframe="initial")


def model_from_mjcf(path: Path, *, keyframe: str | None = None) -> InstrumentedModel:
    """Load a user's MJCF file and instrument every moving body and every possible contact;
    the run starts from the named keyframe, or the model's default pose.

    The log keeps the model's text with its includes inlined and, when it reads mesh or
    texture files, the compiled model (`impactlab.record.model_files`).
    """
    from impactlab.record.model_files import BINARY_ATTACHMENT, binary, model_files, parse_mjcf

    if not path.is_file():
        raise SpecError(str(path), "", "file not found")
    spec = parse_mjcf(path)
    files = model_files(spec, path)
    try:
        inst = instrument(spec, str(path), xml=files.xml, keyframe=keyframe)
    except UnicodeDecodeError:  # MuJoCo keeps names as the file's bytes
        raise SpecError(
            str(path), "", "a name in the model is not UTF-8 text: save the model as UTF-8"
        ) from None
    inst.inputs = files.inputs
    if files.needs_binary:
        inst.attachments = ((BINARY_ATTACHMENT, "application/octet-stream", binary(inst.model)),)
    return inst


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def instrument(
    spec: mujoco.MjSpec,
    source: str,
    *,
    xml: str,
    keyframe: str | None,
) -> InstrumentedModel:
    """Name unnamed bodies and geoms, add the recorder's sensors, compile.

    `xml` is the model's own MJCF text, kept for the log: MuJoCo's saved XML rounds numbers
    to about six digits, the text we were given does not. The sensors do not change the
    dynamics, so that text reproduces the run.

    Raises:
        SpecError: the model does not compile, has no body that moves, or lacks `keyframe`.
    """
    name_unnamed(spec)
    prefix = sensor_prefix(spec)
    try:
        plain = spec.compile()
    except Exception as exc:
        raise SpecError(source, "", f"invalid MJCF: {_one_line(exc)}") from None
    free_bodies = geometry.moving_bodies(plain)
    if not free_bodies:
        raise SpecError(
            source, "", "the model has no body that moves (every body is welded to the world)"
        )
    if keyframe is not None and keyframe not in {plain.key(k).name for k in range(plain.nkey)}:
        known = ", ".join(repr(plain.key(k).name) for k in range(plain.nkey)) or "none"
        raise SpecError(
            source, "keyframe", f"no keyframe named {keyframe!r} (the model has {known})"
        )
    body_names = [plain.body(b).name for b in free_bodies]
    for name in body_names:
        for kind in ("FRAMEPOS", "FRAMEQUAT", "FRAMELINVEL", "FRAMEANGVEL"):
            spec.add_sensor(
                name=f"{prefix}{name}:{kind.lower()}",
                type=getattr(mujoco.mjtSensor, f"mjSENS_{kind}"),
                objtype=mujoco.mjtObj.mjOBJ_BODY,
                objname=name,
            )
    spec.add_sensor(name=f"{prefix}e_potential", type=mujoco.mjtSensor.mjSENS_E_POTENTIAL)
    spec.add_sensor(name=f"{prefix}e_kinetic", type=mujoco.mjtSensor.mjSENS_E_KINETIC)
    for t in sprung_tendons(plain):
        spec.add_sensor(
            name=f"{prefix}{TENDON_SENSOR}{t}",
            type=mujoco.mjtSensor.mjSENS_TENDONPOS,
            objtype=mujoco.mjtObj.mjOBJ_TENDON,
            objname=plain.tendon(t).name,
        )
    pairs = geometry.contact_pairs(plain, set(free_bodies))
    for g1, g2, num in pairs:
        spec.add_sensor(
            name=f"{prefix}contact:{g1}:{g2}",  # ids: geom names may hold ':'
            type=mujoco.mjtSensor.mjSENS_CONTACT,
            objtype=mujoco.mjtObj.mjOBJ_GEOM,
            objname=plain.geom(g1).name,
            reftype=mujoco.mjtObj.mjOBJ_GEOM,
            refname=plain.geom(g2).name,
            intprm=[CONTACT_DATA_BITS, 0, num],
        )
    data = mujoco.MjData(plain)
    mujoco.mj_kinematics(plain, data)  # shapes relative to each body do not depend on the pose
    own = {b: geometry.body_geoms(plain, b) for b in free_bodies}
    ground = geometry.ground_geoms(plain, [g for gs in own.values() for g in gs])
    surfaces = [geometry.surface(plain, data, g) for g in ground]
    measurable = [g for g, s in zip(ground, surfaces, strict=True) if s.distance]
    clearance_plan = _distance_sensors(spec, plain, own, measurable, prefix, between_bodies=False)
    lone = {b: gs for b, gs in own.items() if geometry.motion(plain, b) == "free"}
    gap_plan = _distance_sensors(spec, plain, lone, [], prefix, between_bodies=True)
    model = spec.compile()
    # With the energy flag on, MuJoCo's energy sensors read d.energy, which mj_forward
    # computes after the sensors: one step late. Off, they compute it themselves, at the
    # step. The flag changes no dynamics.
    model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_ENERGY)

    def adr(name: str) -> int:
        return int(model.sensor_adr[model.sensor(f"{prefix}{name}").id])

    def channels(plan: list[tuple[str, str, list[str]]]) -> list[DistanceChannel]:
        return [DistanceChannel(a, b, tuple(adr(n) for n in names)) for a, b, names in plan]

    bodies = [
        BodyChannel(
            name,
            b,
            adr(f"{name}:framepos"),
            geometry.sphere_radius(plain, data, own[b]),
            geometry.shape_name(plain, own[b]),
            geometry.rest_height(plain, data, b, own[b]) if own[b] else None,
            tuple(plain.geom(g).name for g in own[b]),
            geometry.motion(plain, b),
        )
        for name, b in zip(body_names, free_bodies, strict=True)
    ]
    contacts = [
        ContactChannel(
            geom1=model.geom(g1).name,
            geom2=model.geom(g2).name,
            body1=model.body(model.geom_bodyid[g1]).name,
            body2=model.body(model.geom_bodyid[g2]).name,
            adr=adr(f"contact:{g1}:{g2}"),
            num=num,
        )
        for g1, g2, num in pairs
    ]
    key = None if keyframe is None else int(model.key(keyframe).id)
    geoms, meshes = describe_geoms(model, [b.body_id for b in bodies])
    return InstrumentedModel(
        model=model,
        xml=xml,
        bodies=bodies,
        contacts=contacts,
        geoms=geoms,
        energy_adr=adr("e_potential"),
        keyframe=key,
        surfaces=surfaces,
        clearances=channels(clearance_plan),
        gaps=channels(gap_plan),
        static_potential=geometry.static_potential(plain, data),
        joints=joint_energy(model, [adr(f"{TENDON_SENSOR}{t}") for t in sprung_tendons(model)]),
        meshes=meshes,
    )


def _distance_sensors(
    spec: mujoco.MjSpec,
    model: mujoco.MjModel,
    own: dict[int, list[int]],
    surfaces: list[int],
    prefix: str,
    *,
    between_bodies: bool,
) -> list[tuple[str, str, list[str]]]:
    """Add a `distance` sensor per pair of geoms that can collide; returns what each measures.

    Each entry is (body, surface geom or other body, sensor names without the prefix): the
    body's distance to that surface (or body) is the smallest of those sensors. Pairs of
    geoms that cannot collide get no sensor; (body, other) pairs with none are left out.
    """
    free = list(own)
    others: list[tuple[int, str, list[int]]] = []
    for i, b in enumerate(free):
        if between_bodies:
            others += [(b, model.body(o).name, own[o]) for o in free[i + 1 :]]
        else:
            others += [(b, model.geom(g).name, [g]) for g in surfaces]
    plan = []
    for b, other, targets in others:
        names = []
        for g1 in own[b]:
            for g2 in targets:
                if not geometry.can_collide(model, g1, g2):
                    continue
                name = f"distance:{g1}:{g2}"
                spec.add_sensor(
                    name=f"{prefix}{name}",
                    type=mujoco.mjtSensor.mjSENS_GEOMDIST,
                    objtype=mujoco.mjtObj.mjOBJ_GEOM,
                    objname=model.geom(g1).name,
                    reftype=mujoco.mjtObj.mjOBJ_GEOM,
                    refname=model.geom(g2).name,
                    cutoff=DISTANCE_CUTOFF_M,
                )
                names.append(name)
        if names:
            plan.append((model.body(b).name, other, names))
    return plan
