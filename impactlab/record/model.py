"""Build MuJoCo models for recording: from an experiment spec, or any user MJCF, instrumented."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from impactlab.errors import SpecError
from impactlab.logs.checks import PLANE_GEOM
from impactlab.logs.geoms import FlexShape, GeomShape
from impactlab.logs.metadata import Surface
from impactlab.mjcf.load import compile_spec, parse_mjcf
from impactlab.record import geometry
from impactlab.record.contact_pairs import CalibratedPair, calibrated_pairs
from impactlab.record.geoms import describe as describe_geoms
from impactlab.record.geoms import describe_flexes
from impactlab.record.joint_energy import TENDON_SENSOR, JointEnergy, joint_energy, sprung_tendons
from impactlab.record.model_names import name_unnamed, sensor_prefix
from impactlab.record.mujoco_version import require_mujoco  # noqa: F401 (checks at import)
from impactlab.record.spec import RunSpec

BODY_STATE_SIZE = 13  # pos 3, quat 4, linvel 3, angvel 3
DISTANCE_CUTOFF_M = 1.0e4
"""Distances beyond this are reported as this (MuJoCo's distance sensors need a cutoff)."""
MAX_GAP_PAIRS = 10_000
"""Pairs of bodies the separation stop rule may watch (a distance sensor each)."""


@dataclass(frozen=True)
class BodyChannel:
    """A rigid body (`geometry.RigidBody`), where its 13 state values start in sensordata,
    and its shape.

    The state is the rigid body's centre of mass and principal axes (a site the recorder
    adds to its root body) and their world-frame velocities.

    Attributes:
        radius: the radius when the body is one sphere centred at its centre of mass.
        shape: its collision geoms' types ("sphere", "box", "box+sphere", ...).
        rest_height: lowest centre-of-mass height above a flat surface it touches, m.
        geoms: names of its collision geoms.
        motion: "free" (a lone free body: ballistic between contacts) or "articulated".
    """

    name: str
    adr: int
    radius: float | None
    shape: str = "sphere"
    rest_height: float | None = None
    geoms: tuple[str, ...] = ()
    motion: str = "free"
    mass: float = 0.0
    inertia: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class DistanceChannel:
    """A body's distance to a surface (or another body): the min of the sensors at `adrs`."""

    body: str
    other: str
    adrs: tuple[int, ...]


@dataclass
class InstrumentedModel:
    """A compiled model, its MJCF text and the layout of what the recorder reads."""

    model: mujoco.MjModel
    xml: str  # the MJCF text as written by impactlab or the user (full precision)
    bodies: list[BodyChannel]
    geoms: list[GeomShape]
    energy_adr: int
    keyframe: int | None
    surfaces: list[Surface] = field(default_factory=list)
    clearances: dict[str, list[DistanceChannel]] = field(default_factory=dict)  # by body
    gaps: list[DistanceChannel] = field(default_factory=list)  # body to body
    static_potential: float = 0.0  # MuJoCo's potential energy of the static bodies, J
    joints: JointEnergy | None = None  # rotor inertia and springs, if the model has any
    attachments: tuple[tuple[str, str, bytes], ...] = ()  # more files for the log (name, type)
    meshes: dict[str, np.ndarray] = field(default_factory=dict)  # triangles by attachment name
    flexes: list[FlexShape] = field(default_factory=list)  # what draws the flexes
    party: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))  # see `parties`
    party_names: tuple[str, ...] = ()

    def clearance_of(self, body: str) -> list[DistanceChannel]:
        """The body's distance channels to the ground surfaces, in surface order."""
        return self.clearances.get(body, [])

    def initial_state(self) -> np.ndarray:
        """Full physics state at the start of the run (the `initial` keyframe if any), (nstate,)."""
        data = mujoco.MjData(self.model)  # reset: the model's default pose
        if self.keyframe is not None:
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
            f'    <geom name="{PLANE_GEOM}" type="plane" size="{_fmt(run.plane.size)}" '
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
    gaps = run.stop.separation is not None
    spec = mujoco.MjSpec.from_string(xml)
    return instrument(spec, run.source, xml=xml, keyframe="initial", gaps=gaps)


def model_from_mjcf(
    path: Path, *, keyframe: str | None = None, gaps: bool = False
) -> InstrumentedModel:
    """Load a user's MJCF file and instrument it (`instrument`); the run starts from the
    named keyframe, or the model's default pose.

    MuJoCo reads the model and every file it names; the log keeps its text and, when the text
    alone does not reproduce it, the compiled model (`impactlab.record.model_files`).
    """
    from impactlab.record.model_files import binary_attachment, model_files

    spec = parse_mjcf(path)
    files = model_files(spec, path)
    try:
        inst = instrument(spec, str(path), xml=files.xml, keyframe=keyframe, gaps=gaps)
    except UnicodeDecodeError:  # MuJoCo keeps names as the file's bytes
        raise SpecError(
            str(path), "", "a name in the model is not UTF-8 text: save the model as UTF-8"
        ) from None
    if files.needs_binary:
        inst.attachments = (binary_attachment(inst.model),)
    return inst


def instrument(
    spec: mujoco.MjSpec,
    source: str,
    *,
    xml: str,
    keyframe: str | None,
    gaps: bool = False,
) -> InstrumentedModel:
    """Name unnamed bodies and geoms, add the recorder's sites and sensors, compile.

    Per rigid body (`geometry.rigid_bodies`) a site at its centre of mass and principal
    axes with frame sensors on it; MuJoCo's kinetic and potential energy; per pair of a
    body's collision geom and a ground surface a distance sensor (its clearance); with
    `gaps` (a separation stop rule), per pair of free bodies' geoms one too. `xml` is the
    model's MJCF text, kept for the log. The sensors and sites do not change the dynamics.

    Raises:
        SpecError: the model does not compile, lacks `keyframe`, or the separation rule
            would watch more than `MAX_GAP_PAIRS` pairs.
    """
    name_unnamed(spec)
    prefix = sensor_prefix(spec)
    plain = compile_spec(spec, source)
    data = mujoco.MjData(plain)
    mujoco.mj_kinematics(plain, data)
    rigid = geometry.rigid_bodies(plain, data)
    if keyframe is not None and keyframe not in {plain.key(k).name for k in range(plain.nkey)}:
        known = ", ".join(repr(plain.key(k).name) for k in range(plain.nkey)) or "none"
        raise SpecError(
            source, "keyframe", f"no keyframe named {keyframe!r} (the model has {known})"
        )
    names = {r.root: plain.body(r.root).name for r in rigid}
    for r in rigid:
        name = names[r.root]
        site = spec.body(name).add_site(name=f"{prefix}{name}", pos=r.pos, quat=r.quat)
        site.group = 5  # not drawn by MuJoCo's viewer
        for kind in ("FRAMEPOS", "FRAMEQUAT", "FRAMELINVEL", "FRAMEANGVEL"):
            spec.add_sensor(
                name=f"{prefix}{name}:{kind.lower()}",
                type=getattr(mujoco.mjtSensor, f"mjSENS_{kind}"),
                objtype=mujoco.mjtObj.mjOBJ_SITE,
                objname=f"{prefix}{name}",
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
    own = {r.root: geometry.rigid_geoms(plain, r) for r in rigid}
    ground = geometry.ground_geoms(plain, [g for gs in own.values() for g in gs])
    surfaces = [geometry.surface(plain, data, g) for g in ground]
    measurable = [g for g, s in zip(ground, surfaces, strict=True) if s.distance]
    to_ground = [(b, plain.geom(g).name, [g]) for b in own for g in measurable]
    clearance_plan = _distance_sensors(spec, plain, own, to_ground, prefix)
    gap_plan: list[tuple[str, str, list[str]]] = []
    if gaps:
        lone = {r.root: own[r.root] for r in rigid if geometry.motion(plain, r) == "free"}
        pairs = sum(len(a) * len(b) for a, b in itertools.combinations(lone.values(), 2))
        if pairs > MAX_GAP_PAIRS:
            raise SpecError(
                source,
                "stop.separation",
                f"the separation rule would watch {pairs:,} pairs of geoms "
                f"(at most {MAX_GAP_PAIRS:,}): use a time limit instead",
            )
        between = [(a, names[b], lone[b]) for a, b in itertools.combinations(lone, 2)]
        gap_plan = _distance_sensors(spec, plain, own, between, prefix)
    model = compile_spec(spec, source)
    # With the energy flag on, MuJoCo's energy sensors read d.energy, which mj_forward
    # computes after the sensors: one step late. Off, they compute it themselves, at the
    # step. The flag changes no dynamics.
    model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_ENERGY)

    def adr(name: str) -> int:
        return int(model.sensor_adr[model.sensor(f"{prefix}{name}").id])

    def channels(plan: list[tuple[str, str, list[str]]]) -> list[DistanceChannel]:
        return [DistanceChannel(a, b, tuple(adr(n) for n in names)) for a, b, names in plan]

    clearances: dict[str, list[DistanceChannel]] = {}  # by body, in surface order
    for c in channels(clearance_plan):
        clearances.setdefault(c.body, []).append(c)
    bodies = []
    for r in rigid:
        name, mine = names[r.root], own[r.root]
        com = data.xpos[r.root] + data.xmat[r.root].reshape(3, 3) @ np.asarray(r.pos)
        bodies.append(
            BodyChannel(
                name,
                adr(f"{name}:framepos"),
                geometry.sphere_radius(plain, data, com, mine),
                geometry.shape_name(plain, mine),
                geometry.rest_height(plain, data, com, mine) if mine else None,
                tuple(plain.geom(g).name for g in mine),
                geometry.motion(plain, r),
                r.mass,
                r.inertia,
            )
        )
    key = None if keyframe is None else int(model.key(keyframe).id)
    sites = {root: int(model.site(f"{prefix}{n}").id) for root, n in names.items()}
    geoms, meshes = describe_geoms(model, sites)
    flexes = describe_flexes(model, names)
    party, party_names = parties(model, list(names))
    return InstrumentedModel(
        model=model,
        xml=xml,
        bodies=bodies,
        geoms=geoms,
        energy_adr=adr("e_potential"),
        keyframe=key,
        surfaces=surfaces,
        clearances=clearances,
        gaps=channels(gap_plan),
        static_potential=geometry.static_potential(plain, data),
        joints=joint_energy(model, [adr(f"{TENDON_SENSOR}{t}") for t in sprung_tendons(model)]),
        meshes=meshes,
        flexes=flexes,
        party=party,
        party_names=party_names,
    )


def parties(model: mujoco.MjModel, roots: list[int]) -> tuple[np.ndarray, tuple[str, ...]]:
    """Who each side of a contact is: the party of every geom, then of every flex, and the
    parties' names.

    A geom of a rigid body belongs to that body (party = its index in `roots`); a static
    geom is a surface, its own party (`len(roots) + geom id`); a flex is one
    (`len(roots) + ngeom + flex id`).
    """
    index = {root: i for i, root in enumerate(roots)}
    nb, ngeom = len(roots), model.ngeom
    geom_party = [
        index.get(int(model.body_weldid[model.geom_bodyid[g]]), nb + g) for g in range(ngeom)
    ]
    flex_party = [nb + ngeom + f for f in range(model.nflex)]
    names = [model.body(r).name for r in roots]
    names += [model.geom(g).name for g in range(ngeom)]
    names += [geometry.flex_name(model, f) for f in range(model.nflex)]
    return np.array(geom_party + flex_party, np.int64), tuple(names)


def _distance_sensors(
    spec: mujoco.MjSpec,
    model: mujoco.MjModel,
    own: dict[int, list[int]],
    targets: list[tuple[int, str, list[int]]],
    prefix: str,
) -> list[tuple[str, str, list[str]]]:
    """Add a `distance` sensor per pair of geoms that can collide; returns what each measures.

    `targets`: (root body, what it is measured to: a surface geom or another body, that
    one's geoms); `own`: each root body's collision geoms. Each entry returned is (body, other,
    sensor names without the prefix): the body's distance to the other is the smallest of
    those sensors. Pairs of geoms that cannot collide get no sensor; (body, other) pairs
    with none are left out.
    """
    plan = []
    for b, other, geoms in targets:
        names = []
        for g1 in own[b]:
            for g2 in geoms:
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
