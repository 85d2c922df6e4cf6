"""Plain-MuJoCo ground truth for the model zoo: energies, the work of each force, contact episodes."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

# The kinds of force whose work is accounted, in the order the tables print them.
WORK_KINDS = (
    "contact_normal",  # contact rows: the normal part (see run())
    "contact_friction",  # contact rows: the rest (tangential, torsional, rolling)
    "limit",  # joint and tendon limits
    "equality",  # equality constraints (connect, weld, joint, tendon, flex)
    "friction_loss",  # dof and tendon friction loss
    "damper",  # qfrc_damper: joint, tendon and flex-edge damping
    "spring",  # the part of qfrc_spring that MuJoCo's potential energy holds
    "elastic",  # the rest of qfrc_spring: flex elasticity and bending, passive contact
    "gravcomp",  # qfrc_gravcomp where it is passive (not routed through actuators)
    "fluid",  # qfrc_fluid
    "adhesion",  # qfrc_adhesion
    "passive_other",  # qfrc_passive minus the above: passive plugins, mjcb_passive
    "actuator",  # qfrc_actuator
    "applied",  # qfrc_applied and xfrc_applied projected to joints
    "constraint_other",  # efc rows of a type this oracle does not know (none in MuJoCo 4.0)
)
# Work kinds whose energy MuJoCo's potential energy already holds: left out of the residual.
CONSERVATIVE = frozenset({"spring"})

_STATE = mujoco.mjtState.mjSTATE_INTEGRATION
_C = mujoco.mjtConstraint
_CONTACT_TYPES = (
    int(_C.mjCNSTR_CONTACT_FRICTIONLESS),
    int(_C.mjCNSTR_CONTACT_PYRAMIDAL),
    int(_C.mjCNSTR_CONTACT_ELLIPTIC),
)
_ROW_KINDS = {
    int(_C.mjCNSTR_EQUALITY): "equality",
    int(_C.mjCNSTR_FRICTION_DOF): "friction_loss",
    int(_C.mjCNSTR_FRICTION_TENDON): "friction_loss",
    int(_C.mjCNSTR_LIMIT_JOINT): "limit",
    int(_C.mjCNSTR_LIMIT_TENDON): "limit",
}
_FREE, _BALL = int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL)
_PYRAMIDAL = int(_C.mjCNSTR_CONTACT_PYRAMIDAL)
_W = mujoco.mjtWarning
_FATAL_WARNINGS = (_W.mjWARN_BADQPOS, _W.mjWARN_BADQVEL, _W.mjWARN_BADQACC)
_FATAL = [int(w) for w in _FATAL_WARNINGS]
# Integrators whose mj_step leaves every computed field of mjData at the step's start state.
_FIELDS_AT_START = (
    int(mujoco.mjtIntegrator.mjINT_EULER),
    int(mujoco.mjtIntegrator.mjINT_IMPLICIT),
    int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST),
)


@dataclasses.dataclass(frozen=True)
class Episode:
    """One contact episode of a party pair: from the first step with a contact to the last.

    Normal velocities are n . (v2 - v1) in m/s at each contact point (n from party 1 to
    party 2, MuJoCo's contact frame): negative approaching, positive separating.
    """

    party1: str
    party2: str
    onset_step: int
    onset_time: float  # s, the first step with a contact
    release_step: int | None  # the first step without one again; None: still touching at the end
    release_time: float | None
    onset_vn: tuple[float, ...] | None  # at the onset step's state; None: touching at t = 0
    release_vn: tuple[float, ...] | None  # at release, with the last contact step's points
    max_penetration: float  # m, the largest -dist of the episode's contacts (< 0: never overlap)
    work_normal: float  # J, the episode's contact-normal work
    work_friction: float  # J

    @property
    def approach_speed(self) -> float | None:
        """The approach at onset, the mean over the contact points (m/s, > 0 approaching,
        impactlab's -v_in), None when touching at the start."""
        return None if self.onset_vn is None else -float(np.mean(self.onset_vn))

    @property
    def separation_speed(self) -> float | None:
        """The separation at release, the mean over the last step's points (m/s, impactlab's
        v_out), None while still in contact."""
        return None if self.release_vn is None else float(np.mean(self.release_vn))

    @property
    def restitution(self) -> float | None:
        """separation_speed / approach_speed, None when either is missing or no approach."""
        approach, separation = self.approach_speed, self.separation_speed
        if approach is None or separation is None or approach <= 0:
            return None
        return separation / approach


@dataclasses.dataclass(frozen=True)
class Run:
    """What one run gives per logged step (arrays of length nlogged) and per episode."""

    model: str
    keyframe: str | int | None
    timestep: float  # s
    integrator: str
    cone: str
    nsteps: int  # simulated steps
    every: int  # logging stride in steps
    step: IntArray  # the logged steps k: 0, every, 2 every, ..., within nsteps
    time: FloatArray  # s, at each logged step
    kinetic: FloatArray  # J, MuJoCo's energy[1] at the logged state
    potential: FloatArray  # J, MuJoCo's energy[0] at the logged state
    work: Mapping[str, FloatArray]  # J, cumulative work of each kind in WORK_KINDS up to step k
    residual: FloatArray  # J, (E_k - E_0) - sum of the non-conservative works up to step k
    episodes: tuple[Episode, ...]
    stopped: str | None  # why the run ended before nsteps (a MuJoCo warning), else None
    warnings: Mapping[str, int]  # MuJoCo's warning counts at the end
    seconds: float  # wall time of the run
    # J, the part of the residual that the step's velocity change holds beyond the start
    # forces: sum of (M (v_after - v_before) - h f) . (v_before + v_after) / 2 (see run());
    # a diagnostic of the oracle, None where a run does not give it
    acceleration_gap: FloatArray | None = None
    # J, the bodies' gravitational potential energy alone (-sum m_i g . xipos_i), the part
    # of `potential` that is not springs; None where a run does not give it
    gravity_potential: FloatArray | None = None

    @property
    def energy(self) -> FloatArray:
        """Total mechanical energy (J) at each logged step."""
        return self.kinetic + self.potential

    @property
    def energy_scale(self) -> float:
        """A scale for tolerances (J): the largest kinetic energy, potential swing or work."""
        scales = [float(np.max(np.abs(self.kinetic), initial=0.0))]
        if self.potential.size:
            scales.append(float(np.ptp(self.potential)))
        scales += [float(np.max(np.abs(w), initial=0.0)) for w in self.work.values()]
        return max(scales)


def party_names(model: mujoco.MjModel) -> list[str]:
    """Names of the parties, indexed by party id: bodies (0 is the world), then flexes, then
    every geom (a geom that never moves is a party of its own: a surface).

    A moving body's party is the body it is welded to (body_weldid); a flex is its own
    party; a static geom (welded to the world or to a mocap body) is its own.
    """
    names = []
    for body in range(model.nbody):
        name = model.body(body).name
        names.append("world" if body == 0 else name or f"body {body}")
    for flex in range(model.nflex):
        names.append(f"flex {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_FLEX, flex) or flex}")
    for geom in range(model.ngeom):
        names.append(model.geom(geom).name or f"geom {geom}")
    return names


def contact_parties(model: mujoco.MjModel, contacts: Any) -> IntArray:
    """The party ids (ncon, 2) of each contact's two sides (see party_names)."""
    geom = np.asarray(contacts.geom, dtype=np.int64).reshape(-1, 2)
    flex = np.asarray(contacts.flex, dtype=np.int64).reshape(-1, 2)
    weld = np.asarray(model.body_weldid, dtype=np.int64)
    root = weld[np.asarray(model.geom_bodyid, dtype=np.int64)[np.maximum(geom, 0)]]
    static = np.asarray(model.body_dofnum, dtype=np.int64)[root] == 0
    geom_party = np.where(static, model.nbody + model.nflex + np.maximum(geom, 0), root)
    return np.where(geom >= 0, geom_party, model.nbody + flex)


class _SpringInPotential:
    """The part of qfrc_spring whose energy mj_energyPos counts: joints, tendons, 1-D flexes."""

    def __init__(self, m: mujoco.MjModel) -> None:
        self.m = m
        off = bool(m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_SPRING)
        stiff = (m.jnt_stiffness != 0) | np.any(m.jnt_stiffnesspoly != 0, axis=1)
        self.joints = [] if off else [int(j) for j in np.flatnonzero(stiff)]
        tstiff = (m.tendon_stiffness != 0) | np.any(m.tendon_stiffnesspoly != 0, axis=1)
        self.tendons = [] if off else [int(t) for t in np.flatnonzero(tstiff)]
        self.flexes = [
            f
            for f in range(m.nflex)
            if not off and m.flex_dim[f] == 1 and not m.flex_rigid[f] and m.flex_edgestiffness[f]
        ]
        self.empty = not (self.joints or self.tendons or self.flexes)

    def __call__(self, d: mujoco.MjData, qpos: FloatArray) -> FloatArray:
        """The force at qpos, with ten_J, ten_length and flexedge_* from d (computed there)."""
        m = self.m
        force = np.zeros(m.nv)
        for j in self.joints:
            k, poly = m.jnt_stiffness[j], m.jnt_stiffnesspoly[j]
            padr, dadr = m.jnt_qposadr[j], m.jnt_dofadr[j]
            jtype = int(m.jnt_type[j])
            if jtype == _FREE:
                dif = qpos[padr : padr + 3] - m.qpos_spring[padr : padr + 3]
                force[dadr : dadr + 3] -= _poly_force(k, poly, float(np.linalg.norm(dif))) * dif
                padr, dadr = padr + 3, dadr + 3
            if jtype in (_FREE, _BALL):
                quat = qpos[padr : padr + 4] / np.linalg.norm(qpos[padr : padr + 4])
                dif = np.zeros(3)
                mujoco.mju_subQuat(dif, quat, m.qpos_spring[padr : padr + 4])
                force[dadr : dadr + 3] -= _poly_force(k, poly, float(np.linalg.norm(dif))) * dif
            else:
                x = qpos[padr] - m.qpos_spring[padr]
                force[dadr] -= x * _poly_force(k, poly, float(x))
        for t in self.tendons:
            length, (lower, upper) = d.ten_length[t], m.tendon_lengthspring[t]
            x = length - upper if length > upper else length - lower if length < lower else 0.0
            frc = -x * _poly_force(m.tendon_stiffness[t], m.tendon_stiffnesspoly[t], x)
            adr, nnz = m.ten_J_rowadr[t], m.ten_J_rownnz[t]
            cols = m.ten_J_colind[adr : adr + nnz]
            np.add.at(force, cols, d.ten_J[adr : adr + nnz] * frc)
        for f in self.flexes:
            k = m.flex_edgestiffness[f]
            for e in range(m.flex_edgeadr[f], m.flex_edgeadr[f] + m.flex_edgenum[f]):
                if m.flexedge_rigid[e]:
                    continue
                frc = k * (m.flexedge_length0[e] - d.flexedge_length[e])
                adr, nnz = m.flexedge_J_rowadr[e], m.flexedge_J_rownnz[e]
                cols = m.flexedge_J_colind[adr : adr + nnz]
                np.add.at(force, cols, d.flexedge_J[adr : adr + nnz] * frc)
        return force


def _poly_force(linear: float, poly: FloatArray, x: float) -> float:
    """MuJoCo's mju_polyForce for springs: linear + sum_i poly[i] x^(i+1)."""
    return float(linear + sum(c * x ** (i + 1) for i, c in enumerate(poly) if c))


class _Contacts:
    """One step's active contacts (exclude == 0), copied out of mjData."""

    FIELDS = (
        "pos", "frame", "dist", "geom", "flex", "elem", "vert", "dim", "friction", "mu",
        "solref", "solreffriction", "solimp", "includemargin", "H", "surfacevel",
    )  # fmt: skip

    def __init__(self, model: mujoco.MjModel, d: mujoco.MjData, nparty: int) -> None:
        self.index = np.zeros(0, np.int64)  # into d.contact at this step
        self.values: dict[str, np.ndarray] = {}
        self.pair = np.zeros(0, np.int64)  # one key per unordered party pair
        self.dist = np.zeros(0)
        if d.ncon:
            contacts = d.contact
            self.index = np.flatnonzero(np.asarray(contacts.exclude) == 0)
            self.values = {f: np.array(getattr(contacts, f))[self.index] for f in self.FIELDS}
            parties = contact_parties(model, contacts)[self.index]
            self.pair = parties.min(axis=1) * nparty + parties.max(axis=1)
            self.dist = self.values["dist"]
        # the distinct pairs, and each contact's index into them
        self.pairs, self.inverse = np.unique(self.pair, return_inverse=True)

    def rows(self, pair: int) -> IntArray:
        return np.flatnonzero(self.pair == pair)

    def contact(self, row: int) -> mujoco.MjContact:
        contact = mujoco.MjContact()
        for field, values in self.values.items():
            setattr(contact, field, values[row])
        return contact


class _NormalVelocity:
    """MuJoCo's own normal-row velocities of given contacts at a given state (scratch mjData)."""

    def __init__(self, m: mujoco.MjModel) -> None:
        self.m = m
        self.d = mujoco.MjData(m)

    def __call__(
        self,
        state: FloatArray,
        contacts: _Contacts,
        rows: IntArray,
        qvel: FloatArray | None = None,
    ) -> tuple[float, ...]:
        """J_n v of the contacts at `state` (its Jacobian), with `qvel` (default: the state's)."""
        m, d = self.m, self.d
        mujoco.mj_setState(m, d, state, _STATE)
        if qvel is not None:
            d.qvel[:] = qvel
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_flex(m, d)
        mujoco.mj_tendon(m, d)
        d.ncon = 0
        for row in rows:
            mujoco.mj_addContact(m, d, contacts.contact(int(row)))
        mujoco.mj_makeConstraint(m, d)
        velocity = np.zeros(d.nefc)
        mujoco.mj_mulJacVec(m, d, velocity, d.qvel)
        adr = np.asarray(d.contact.efc_address)[: len(rows)]
        if not d.nefc:  # no contact has rows: none moves a dof
            return tuple(0.0 for _ in rows)
        first = np.maximum(adr, 0)
        pyramid = d.efc_type[first] == _PYRAMIDAL
        second = np.minimum(first + 1, d.nefc - 1)
        normal = np.where(pyramid, 0.5 * (velocity[first] + velocity[second]), velocity[first])
        # a contact without rows moves no dof: its sides do not move relative to each other
        return tuple(float(v) if a >= 0 else 0.0 for v, a in zip(normal, adr, strict=True))


@dataclasses.dataclass
class _OpenEpisode:
    pair: int
    onset_step: int
    onset_time: float
    onset_vn: tuple[float, ...] | None
    max_penetration: float
    work_normal: float = 0.0
    work_friction: float = 0.0
    # a release not yet certain: (step, time, normal velocities), until MERGE_STEPS apart
    parted: tuple[int, float, tuple[float, ...]] | None = None


MERGE_STEPS = 10
"""Contacts of a pair fewer than this many steps apart are one episode (impactlab's rule)."""


_SMOOTH_KINDS = (
    "damper", "spring", "elastic", "gravcomp", "fluid", "adhesion", "passive_other", "actuator",
    "applied",
)  # fmt: skip
_ROW_KIND_NAMES = ("contact", "equality", "friction_loss", "limit", "constraint_other")


class _StepWork:
    """The work of each kind over one step, and each active contact's normal and friction work.

    Work is h f . (v0 + v1) / 2 with f from src (computed at the step's start, where qpos was
    qpos0), v0 and v1 the velocities before and after the step; a constraint row's work is
    h f_i (J_i v0 + J_i v1) / 2.
    """

    def __init__(self, m: mujoco.MjModel) -> None:
        self.m = m
        self.h = float(m.opt.timestep)
        self.spring = _SpringInPotential(m)
        actgravcomp = np.asarray(m.jnt_actgravcomp, bool)[m.dof_jntid] if m.nv else np.zeros(0)
        self.passive_gravcomp = ~np.asarray(actgravcomp, bool)
        self.forces = np.zeros((len(_SMOOTH_KINDS), m.nv))
        # efc type -> index into _ROW_KIND_NAMES
        self.row_kind = np.full(max(_CONTACT_TYPES + tuple(_ROW_KINDS)) + 1, 4, np.int64)
        self.row_kind[list(_CONTACT_TYPES)] = 0
        for ctype, kind in _ROW_KINDS.items():
            self.row_kind[ctype] = _ROW_KIND_NAMES.index(kind)

    def __call__(
        self,
        src: mujoco.MjData,
        qpos0: FloatArray,
        v0: FloatArray,
        v1: FloatArray,
        contacts: _Contacts,
    ) -> tuple[dict[str, float], FloatArray, FloatArray]:
        m, h, f = self.m, self.h, self.forces
        gravcomp = src.qfrc_gravcomp * self.passive_gravcomp
        f[0] = src.qfrc_damper
        f[1] = 0.0 if self.spring.empty else self.spring(src, qpos0)
        f[2] = src.qfrc_spring - f[1]
        f[3] = gravcomp
        f[4] = src.qfrc_fluid
        f[5] = src.qfrc_adhesion
        f[6] = src.qfrc_passive - src.qfrc_spring - src.qfrc_damper - src.qfrc_fluid
        f[6] -= src.qfrc_adhesion + gravcomp
        f[7] = src.qfrc_actuator
        f[8] = src.qfrc_smooth - src.qfrc_passive + src.qfrc_bias - src.qfrc_actuator
        work = dict.fromkeys(WORK_KINDS, 0.0)
        work.update(zip(_SMOOTH_KINDS, (h * (f @ (0.5 * (v0 + v1)))).tolist(), strict=True))
        ncontact = len(contacts.index)
        normal = np.zeros(ncontact)
        total = np.zeros(ncontact)
        nefc = src.nefc
        if not nefc:
            return work, normal, total
        force = src.efc_force[:nefc]
        vel0 = src.efc_vel[:nefc]
        vel1 = np.zeros(nefc)
        mujoco.mj_mulJacVec(m, src, vel1, v1)
        row_work = h * force * 0.5 * (vel0 + vel1)
        types = np.asarray(src.efc_type[:nefc])
        kinds = self.row_kind[np.minimum(types, self.row_kind.size - 1)]
        by_kind = np.bincount(kinds, weights=row_work, minlength=len(_ROW_KIND_NAMES))
        work["equality"] = float(by_kind[1])
        work["friction_loss"] = float(by_kind[2])
        work["limit"] = float(by_kind[3])
        work["constraint_other"] = float(by_kind[4])
        if by_kind[0] == 0 and not np.any(kinds == 0):
            return work, normal, total
        is_contact = kinds == 0
        cid = np.asarray(src.efc_id[:nefc])[is_contact]
        ncon = src.ncon
        per_contact = np.bincount(cid, weights=row_work[is_contact], minlength=ncon)
        adr = np.asarray(src.contact.efc_address)[:ncon]
        has_rows = adr >= 0
        first = np.where(has_rows, adr, 0)
        pyramid = has_rows & (types[first] == _PYRAMIDAL)
        second = np.minimum(first + 1, nefc - 1)
        sum_force = np.bincount(cid, weights=force[is_contact], minlength=ncon)
        vn0 = np.where(pyramid, 0.5 * (vel0[first] + vel0[second]), vel0[first])
        vn1 = np.where(pyramid, 0.5 * (vel1[first] + vel1[second]), vel1[first])
        fn = np.where(pyramid, sum_force, force[first])
        per_normal = np.where(has_rows, h * fn * 0.5 * (vn0 + vn1), 0.0)
        work["contact_normal"] = float(per_normal.sum())
        work["contact_friction"] = float(by_kind[0] - work["contact_normal"])
        normal = np.asarray(per_normal[contacts.index], dtype=np.float64)
        total = np.asarray(per_contact[contacts.index], dtype=np.float64)
        return work, normal, total - normal


def _keyframe_id(m: mujoco.MjModel, keyframe: str | int) -> int:
    if isinstance(keyframe, str):
        key = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, keyframe)
        if key < 0:
            raise ValueError(f"model has no keyframe named {keyframe!r}")
        return int(key)
    if not 0 <= keyframe < m.nkey:
        raise ValueError(f"keyframe {keyframe} out of range: the model has {m.nkey}")
    return keyframe


def load(
    model_path: str | Path, keyframe: str | int | None = None
) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """Compile a model from its file (MuJoCo resolves includes and assets) and set its start."""
    m = mujoco.MjModel.from_xml_path(str(model_path))
    d = mujoco.MjData(m)
    if keyframe is not None:
        mujoco.mj_resetDataKeyframe(m, d, _keyframe_id(m, keyframe))
    return m, d


def run(
    model_path: str | Path,
    duration: float,
    every: int = 1,
    *,
    keyframe: str | int | None = None,
) -> Run:
    """Simulate a model with plain mj_step and account energy, work and contact episodes.

    Args:
      model_path: an MJCF file; MuJoCo resolves its includes and assets from there.
      duration: simulated time in s; round(duration / timestep) steps are taken.
      every: the logging stride in steps (the works and episodes still cover every step).
      keyframe: a keyframe name or index to start from; None starts at qpos0.

    Returns:
      A Run: per logged step k (0, every, ...), the time, MuJoCo's kinetic and potential
      energy (the energy flag on, computed at the state of step k), the cumulative work of each
      kind of force (WORK_KINDS) over steps 0 .. k-1, and the residual; and the contact
      episodes of every party pair, found at every step whatever the stride.

    Definitions:
      Work of one step: h f . (v_before + v_after) / 2, with f MuJoCo's force of that kind at
      the step's start state (the one mj_forward computes inside mj_step). Constraint rows
      (efc) are split by type: contacts, limits, equality, friction loss; a row's work is
      h f_i (J_i v_before + J_i v_after) / 2, J_i v_before = efc_vel and J_i v_after from
      mj_mulJacVec with the start state's Jacobian. Contact normal: frictionless and elliptic
      contacts' first row; pyramidal contacts' normal force is the sum of their rows' forces
      and their normal velocity the mean of their first two rows' (n + mu t and n - mu t).
      Contact friction is the rest of the contact rows' work.
      For semi-implicit Euler with a constant mass matrix the works of all forces (gravity and
      bias included) add up to the kinetic energy change exactly.

      Conservative, and so not in the residual: gravity and the springs that MuJoCo's
      potential energy (mj_energyPos) holds: joint springs, tendon springs and the edge springs
      of 1-D flexes ("spring", computed here from the model as mj_passive does). The rest of
      qfrc_spring (flex elasticity and bending of 2-D and 3-D flexes, their edge springs,
      passive contact forces) has no potential in MuJoCo's energy: it is "elastic" and counts
      as non-conservative. residual_k = (E_k - E_0) - sum of the works of every kind except
      CONSERVATIVE up to step k: what the integrator adds (for Euler, gravity's share is
      m g h (v_z,k - v_z,0) / 2: -m g^2 h t / 2 in free fall), the Coriolis terms' and the
      changing mass matrix's share, Euler's implicit joint damping (it applies -B v_after,
      the account books the start force -B v_before), and what the constraint solver leaves
      of M qacc - qfrc_smooth - qfrc_constraint.
      acceleration_gap_k: the sum over steps of (M dv - h f) . (v_before + v_after) / 2, with
      M the start state's mass matrix, dv the step's velocity change and f = qfrc_smooth +
      qfrc_constraint (gravity and bias included): the share of the residual that comes
      from a velocity update other than M^-1 f (the solver's imbalance, Euler's implicit
      damping, implicit integrators, RK4's stages). It is zero for Euler with a converged
      solver and no damping; residual - acceleration_gap is then gravity's discretization
      and the mass matrix's change.
      Gravity compensation routed through actuators (actgravcomp) is in "actuator".

      RK4: MuJoCo evaluates forces at four stages and leaves mjData at the last; here the
      forces are those of a separate mj_forward at the step's start state (the first stage),
      so a step's work is the trapezoid of the start force over the step, not the four-stage
      RK4 average, and the difference between the two is in the residual. The same holds
      for any integrator other than Euler, implicit and implicitfast.

      Contacts: a contact exists at step k when MuJoCo's collision at the state of step k
      lists it with exclude == 0 (it has constraint rows; margin contacts included). A party
      is a rigid body as MuJoCo welds it (body_weldid: a massless or welded child belongs to
      the body it is welded to, static geoms to "world"); a flex is its own party. An
      episode of a party pair runs from the first step any contact between them exists to
      the last, contacts fewer than MERGE_STEPS steps apart merged (impactlab's rule); its
      release is the first step after that. A static geom is a party of its own. onset_vn:
      J_n v of each onset contact (its point and normal) evaluated by MuJoCo
      (mj_makeConstraint, mj_mulJacVec) at the onset step's state, with its velocity before
      any contact force acted (the velocity the surfaces met with: the state's own, for RK4
      the previous step's start, whose later stages met the contact); release_vn: the same for each contact of the last contact step, with that
      step's Jacobian and the velocity after it (the one they parted with). The episode's
      speeds are the means over its points. max_penetration: the largest -dist.

      A run stops early (Run.stopped) at MuJoCo's bad qpos/qvel/qacc warning, whose reset
      would make the accounts meaningless, or at a non-finite energy.
    """
    if every < 1:
        raise ValueError(f"every must be >= 1, got {every}")
    started = time.perf_counter()
    m, d = load(model_path, keyframe)
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    h = float(m.opt.timestep)
    nsteps = round(duration / h)
    if nsteps < 1:
        raise ValueError(f"duration {duration} s is shorter than one step of {h} s")
    fields_at_start = int(m.opt.integrator) in _FIELDS_AT_START
    start = None if fields_at_start else mujoco.MjData(m)
    step_work = _StepWork(m)
    names = party_names(m)
    nparty = len(names)
    normal_velocity = _NormalVelocity(m)
    state_size = mujoco.mj_stateSize(m, _STATE)

    nlog = nsteps // every + 1
    logged_step = np.arange(nlog, dtype=np.int64) * every
    times, kinetic, potential, residual, gap, gravity = (np.full(nlog, np.nan) for _ in range(6))
    gravity_on = not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_GRAVITY
    weight = -np.asarray(m.body_mass)[:, None] * np.asarray(m.opt.gravity)[None, :]
    gap_sum = 0.0
    mdv = np.zeros(m.nv)
    work_log = {kind: np.full(nlog, np.nan) for kind in WORK_KINDS}
    cumulative = dict.fromkeys(WORK_KINDS, 0.0)
    episodes: list[Episode] = []
    open_episodes: dict[int, _OpenEpisode] = {}
    previous_state: FloatArray | None = None
    previous_contacts: _Contacts | None = None
    previous_v0: FloatArray | None = None  # RK4: the onset's velocity in (see above)
    energy0 = math.nan
    stopped: str | None = None
    nlogged = 0

    def close(
        episode: _OpenEpisode, step: int, t: float | None, vn: tuple[float, ...] | None
    ) -> None:
        low, high = divmod(episode.pair, nparty)
        episodes.append(
            Episode(
                party1=names[low],
                party2=names[high],
                onset_step=episode.onset_step,
                onset_time=episode.onset_time,
                release_step=step if t is not None else None,
                release_time=t,
                onset_vn=episode.onset_vn,
                release_vn=vn,
                max_penetration=episode.max_penetration,
                work_normal=episode.work_normal,
                work_friction=episode.work_friction,
            )
        )

    for k in range(nsteps + 1):
        state = np.empty(state_size)
        mujoco.mj_getState(m, d, state, _STATE)
        t_k = float(d.time)
        qpos0, v0 = d.qpos.copy(), d.qvel.copy()
        warnings_before = int(d.warning.number[_FATAL].sum())
        if k == nsteps:
            mujoco.mj_forward(m, d)
            src = d
        elif fields_at_start:
            mujoco.mj_step(m, d)
            src = d
        else:
            assert start is not None
            mujoco.mj_setState(m, start, state, _STATE)
            mujoco.mj_forward(m, start)
            mujoco.mj_step(m, d)
            src = start
        fatal = int(d.warning.number[_FATAL].sum()) - warnings_before
        energy = float(src.energy[0] + src.energy[1])
        if fatal or not math.isfinite(energy):
            stopped = (
                f"step {k} (t = {t_k:.6g} s): MuJoCo warning "
                + ", ".join(_W(w).name for w in _FATAL_WARNINGS if d.warning[w].number)
                if fatal
                else f"step {k} (t = {t_k:.6g} s): energy is not finite"
            )
            break
        if k == 0:
            energy0 = energy

        contacts = _Contacts(m, src, nparty)
        current = set(contacts.pairs.tolist())
        for pair in sorted(set(open_episodes) - current):
            episode = open_episodes[pair]
            if episode.parted is None:  # the last contact step's points, the new velocity
                assert previous_contacts is not None and previous_state is not None
                rows = previous_contacts.rows(pair)
                vn = normal_velocity(previous_state, previous_contacts, rows, v0)
                episode.parted = (k, t_k, vn)
            elif k - episode.parted[0] >= MERGE_STEPS - 1:
                close(open_episodes.pop(pair), *episode.parted)
        for pair in sorted(current & set(open_episodes)):
            open_episodes[pair].parted = None  # touching again within MERGE_STEPS: one episode
        for pair in sorted(current - set(open_episodes)):
            rows = contacts.rows(pair)
            before = None if fields_at_start else previous_v0
            onset_vn = None if k == 0 else normal_velocity(state, contacts, rows, before)
            open_episodes[pair] = _OpenEpisode(pair, k, t_k, onset_vn, -math.inf)
        if contacts.pair.size:
            deepest = np.full(len(contacts.pairs), -np.inf)
            np.maximum.at(deepest, contacts.inverse, -contacts.dist)
            for pair, depth in zip(contacts.pairs.tolist(), deepest.tolist(), strict=True):
                episode = open_episodes[pair]
                episode.max_penetration = max(episode.max_penetration, depth)

        if k % every == 0:
            i = k // every
            times[i], kinetic[i], potential[i] = t_k, src.energy[1], src.energy[0]
            nonconservative = 0.0
            for kind in WORK_KINDS:
                work_log[kind][i] = cumulative[kind]
                if kind not in CONSERVATIVE:
                    nonconservative += cumulative[kind]
            residual[i] = (energy - energy0) - nonconservative
            gap[i] = gap_sum
            gravity[i] = float(np.sum(weight[1:] * src.xipos[1:])) if gravity_on else 0.0
            nlogged = i + 1
        if k == nsteps:
            break
        v1 = d.qvel.copy()
        works, normal, friction = step_work(src, qpos0, v0, v1, contacts)
        mujoco.mj_mulM(m, src, mdv, v1 - v0)
        unbalanced = mdv - h * (src.qfrc_smooth + src.qfrc_constraint)
        gap_sum += float(unbalanced @ (0.5 * (v0 + v1)))
        for kind, value in works.items():
            cumulative[kind] += value
        if contacts.pair.size:
            wn = np.bincount(contacts.inverse, weights=normal)
            wf = np.bincount(contacts.inverse, weights=friction)
            pairs = contacts.pairs.tolist()
            for pair, n_work, f_work in zip(pairs, wn.tolist(), wf.tolist(), strict=True):
                open_episodes[pair].work_normal += n_work
                open_episodes[pair].work_friction += f_work
        previous_state, previous_contacts, previous_v0 = state, contacts, v0

    for pair in sorted(open_episodes):
        parted = open_episodes[pair].parted
        close(open_episodes[pair], *(parted if parted is not None else (-1, None, None)))
    episodes.sort(key=lambda e: (e.onset_step, e.party1, e.party2))
    return Run(
        model=str(model_path),
        keyframe=keyframe,
        timestep=h,
        integrator=mujoco.mjtIntegrator(m.opt.integrator).name.removeprefix("mjINT_"),
        cone=mujoco.mjtCone(m.opt.cone).name.removeprefix("mjCONE_"),
        nsteps=nsteps,
        every=every,
        step=logged_step[:nlogged],
        time=times[:nlogged],
        kinetic=kinetic[:nlogged],
        potential=potential[:nlogged],
        work={kind: values[:nlogged] for kind, values in work_log.items()},
        residual=residual[:nlogged],
        acceleration_gap=gap[:nlogged],
        gravity_potential=gravity[:nlogged],
        episodes=tuple(episodes),
        stopped=stopped,
        warnings={_W(w).name: int(d.warning[w].number) for w in range(len(d.warning))},
        seconds=time.perf_counter() - started,
    )


def springs_booked_as_work(run: Run) -> Run:
    """The same run in the other convention: springs as a work, gravity alone as potential.

    potential becomes gravity_potential, work "spring" holds all of qfrc_spring's work
    ("spring" + "elastic"), "elastic" none, and the residual is (E - E_0) - the sum of every
    kind's work, E = kinetic + gravity_potential.
    """
    if run.gravity_potential is None:
        raise ValueError("the run has no gravity_potential to convert with")
    work = dict(run.work)
    work["spring"] = run.work["spring"] + run.work["elastic"]
    work["elastic"] = np.zeros_like(run.work["elastic"])
    energy = run.kinetic + run.gravity_potential
    total = np.sum([work[kind] for kind in WORK_KINDS], axis=0)
    residual = (energy - energy[0]) - total if energy.size else energy
    return dataclasses.replace(run, potential=run.gravity_potential, work=work, residual=residual)
