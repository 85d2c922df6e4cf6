"""What a log holds, as the writer takes it: the run's header, its rows and its outcome."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from impactlab.logs import contract
from impactlab.logs import format as logformat
from impactlab.logs.geoms import FlexShape
from impactlab.logs.scene import GeomShape
from impactlab.physics import half_step_s
from impactlab.version import __version__


@dataclass(frozen=True)
class BodyMeta:
    """A free body as the run metadata describes it: mass kg, principal inertia kg m^2, radius m.

    `radius` is set when the body is one sphere centred at its centre of mass; `shape` names
    its collision geoms' types, `geoms` the geoms, and `rest_height_m` is the lowest height
    its centre of mass can have above a flat surface it touches (None: no collision geom).
    `motion` is "free" for a lone free body (ballistic between contacts), "articulated" for
    a body of a jointed or welded tree.
    """

    name: str
    mass: float
    inertia: tuple[float, float, float]
    radius: float | None = None
    shape: str = ""
    rest_height_m: float | None = None
    geoms: tuple[str, ...] = ()
    motion: str = "free"


@dataclass(frozen=True)
class SurfaceMeta:
    """A ground surface: a static geom free bodies can land on.

    Attributes:
        name: the geom's name.
        type: its type (plane, box, mesh, ...).
        level_m: its highest point along -gravity, m (a plane: the height of its origin).
        distance: whether MuJoCo measures the bodies' distance to it (not for height fields).
    """

    name: str
    type: str
    level_m: float
    distance: bool = True


@dataclass(frozen=True)
class RunMeta:
    """What the `impactlab.run` metadata record says (see `impactlab.logs.format.RUN_KEYS`).

    The keys of format 2 (`impactlab.logs.contract`): `contact_targets` (the calibrated
    pairs), `geom_contact` (the solref and solimp every geom shares, None: they differ),
    `separation_m` (the separation stop rule, None: none); `half_step_s` is the integrator's.
    """

    experiment: str
    description: str
    source: str
    run_id: str
    spec: Mapping[str, Any]
    sweep: Mapping[str, Any]
    spec_hash: str
    timestep_s: float
    log_every: int
    gravity: tuple[float, float, float]
    bodies: Sequence[BodyMeta]
    plane_z: float | None
    mujoco_version: str
    sweep_index: int = 0
    sweep_size: int = 1
    integrator: str = ""
    surfaces: Sequence[SurfaceMeta] = ()
    static_potential_J: float = 0.0
    contact_targets: Sequence[contract.PairTarget] = ()
    geom_contact: contract.GeomContact | None = None
    separation_m: float | None = None

    def record(self) -> dict[str, str]:
        """The metadata record, every value a string."""
        meta = {
            "log_format_version": logformat.LOG_FORMAT_VERSION,
            "impactlab_version": __version__,
            "mujoco_version": self.mujoco_version,
            "experiment": self.experiment,
            "description": self.description,
            "source": self.source,
            "run_id": self.run_id,
            "spec": json.dumps(self.spec, sort_keys=True),
            "sweep": json.dumps(self.sweep, sort_keys=True),
            "sweep_index": str(self.sweep_index),
            "sweep_size": str(self.sweep_size),
            "spec_hash": self.spec_hash,
            "timestep_s": repr(float(self.timestep_s)),
            "log_every": str(self.log_every),
            "gravity": json.dumps([float(x) for x in self.gravity]),
            "bodies": json.dumps(
                [
                    {
                        "name": b.name,
                        "mass": float(b.mass),
                        "inertia": [float(x) for x in b.inertia],
                        "radius": b.radius,
                        "shape": b.shape,
                        "rest_height_m": b.rest_height_m,
                        "geoms": list(b.geoms),
                        **({} if b.motion == "free" else {"motion": b.motion}),
                    }
                    for b in self.bodies
                ]
            ),
            "plane_z": "" if self.plane_z is None else repr(float(self.plane_z)),
            "integrator": self.integrator,
            "ground": json.dumps(
                [
                    {"name": s.name, "type": s.type, "level_m": s.level_m, "distance": s.distance}
                    for s in self.surfaces
                ]
            ),
            "static_potential_J": repr(float(self.static_potential_J)),
            **contract.record_values(
                self.contact_targets,
                self.geom_contact,
                self.separation_m,
                half_step_s(self.integrator, self.timestep_s),
            ),
        }
        assert tuple(meta) == logformat.RUN_KEYS
        return meta


@dataclass(frozen=True)
class LogHeader:
    """Everything a log holds besides its rows: the run, its scene and its model.

    `clearance` lists, per body with a clearance channel, the names of the surfaces its
    distances are measured to, in value order. `meshes`: the triangles (m, 3, 3) of the
    geoms' meshes by attachment name (`impactlab.logs.geoms`).
    """

    run: RunMeta
    geoms: Sequence[GeomShape]
    model_xml: str
    clearance: Sequence[tuple[str, tuple[str, ...]]] = ()
    joint_energy: bool = False  # whether rows carry `joint_energy` (`/energy/joints`)
    attachments: Sequence[tuple[str, str, bytes]] = ()  # more files: name, media type, data
    meshes: Mapping[str, np.ndarray] = field(default_factory=dict)
    flexes: Sequence[FlexShape] = ()
    contact_sides: Mapping[str, Sequence[str]] = field(default_factory=dict)
    """The /contacts channel's metadata: `geoms` (every geom's name, by id), `bodies` (the
    party each geom belongs to: its rigid body, or itself for a static geom), `flexes`
    (every flex's name, by id): what a point's sides (`ContactPoint.geom1`) refer to."""


@dataclass(frozen=True)
class Outcome:
    """How the run ended (the `impactlab.outcome` record and the /events messages)."""

    outcome: str  # completed | unstable
    reason: str
    steps: int
    warnings: Sequence[str] = ()

    def record(self) -> dict[str, str]:
        """The metadata record, every value a string."""
        meta = {
            "outcome": self.outcome,
            "reason": self.reason,
            "warnings": json.dumps(list(self.warnings)),
            "steps": str(self.steps),
        }
        assert tuple(meta) == logformat.OUTCOME_KEYS
        return meta


@dataclass
class LogRows:
    """Consecutive logged rows of a run.

    Attributes:
        t_ns: simulation time of each row, integer ns, (n,).
        bodies: state of each body in `RunMeta.bodies` order, (n, nbody, 13) in
            `messages.BODY_FIELDS` order.
        energy: MuJoCo's kinetic, potential and total energy, J, (n, 3).
        work: the work of each kind of force from the run's start to each row, J, (n, k) in
            `messages.WORK_FIELDS` order.
        contacts: one entry per contact point, by row: its row (m,), its sides (m, 2) (a
            geom id, or -1 - a flex id) and its values (m, 13) in `messages.POINT_FIELDS`
            order.
        clearance: per body in `LogHeader.clearance` order, its distance to each of its
            surfaces, (n, k) m.
        joint_energy: the joints' rotor kinetic, spring potential and their total energy,
            J, (n, 3), when `LogHeader.joint_energy`.
    """

    t_ns: np.ndarray
    bodies: np.ndarray
    energy: np.ndarray
    work: np.ndarray
    contacts: tuple[np.ndarray, np.ndarray, np.ndarray]
    clearance: list[np.ndarray] = field(default_factory=list)
    joint_energy: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.t_ns.size)

    def slice(self, lo: int, hi: int) -> LogRows:
        """Rows lo .. hi - 1."""
        row, sides, values = self.contacts
        mine = (row >= lo) & (row < hi)
        return LogRows(
            self.t_ns[lo:hi],
            self.bodies[lo:hi],
            self.energy[lo:hi],
            self.work[lo:hi],
            (row[mine] - lo, sides[mine], values[mine]),
            [c[lo:hi] for c in self.clearance],
            None if self.joint_energy is None else self.joint_energy[lo:hi],
        )

    @staticmethod
    def concat(parts: Sequence[LogRows]) -> LogRows:
        """The rows of `parts`, one after the other."""
        if len(parts) == 1:
            return parts[0]
        offsets = np.cumsum([0] + [len(p) for p in parts[:-1]])
        return LogRows(
            np.concatenate([p.t_ns for p in parts]),
            np.concatenate([p.bodies for p in parts]),
            np.concatenate([p.energy for p in parts]),
            np.concatenate([p.work for p in parts]),
            (
                np.concatenate([p.contacts[0] + o for p, o in zip(parts, offsets, strict=True)]),
                np.concatenate([p.contacts[1] for p in parts]),
                np.concatenate([p.contacts[2] for p in parts]),
            ),
            [
                np.concatenate([p.clearance[i] for p in parts])
                for i in range(len(parts[0].clearance))
            ],
            None
            if parts[0].joint_energy is None
            else np.concatenate([p.joint_energy for p in parts]),
        )
