"""The work of each kind of force MuJoCo applies, at every step: the run's energy budget."""

from __future__ import annotations

import mujoco
import numpy as np

WORK_KINDS = (
    "contact_normal",
    "contact_friction",
    "springs",
    "damping",
    "limits",
    "equality",
    "friction_loss",
    "actuators",
    "fluid",
    "gravity_compensation",
    "solver",
)
"""What the budget books work to, in order (`schemas/impactlab.proto`'s `Work`). Gravity is
the one force booked as potential energy: the budget's energy is MuJoCo's kinetic energy
plus the bodies' gravitational potential energy."""
KIND = {name: i for i, name in enumerate(WORK_KINDS)}

_GENERALISED = {  # forces MuJoCo keeps per dof, and the mjData array holding each
    "springs": "qfrc_spring",
    "damping": "qfrc_damper",
    "fluid": "qfrc_fluid",
    "gravity_compensation": "qfrc_gravcomp",
    "actuators": "qfrc_actuator",
}
_CONSTRAINTS = {  # MuJoCo's other constraint types, and what the budget books them as
    int(mujoco.mjtConstraint.mjCNSTR_EQUALITY): KIND["equality"],
    int(mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF): KIND["friction_loss"],
    int(mujoco.mjtConstraint.mjCNSTR_FRICTION_TENDON): KIND["friction_loss"],
    int(mujoco.mjtConstraint.mjCNSTR_LIMIT_JOINT): KIND["limits"],
    int(mujoco.mjtConstraint.mjCNSTR_LIMIT_TENDON): KIND["limits"],
}


def generalised_forces(model: mujoco.MjModel) -> list[tuple[int, str]]:
    """(kind, mjData array) of every per-dof force the model can have; one that is zero by
    construction (no spring, no damper, no fluid, no gravity compensation, no actuator)
    is left out, so the recorder copies only what can do work."""
    off = int(model.opt.disableflags)
    flags = mujoco.mjtDisableBit
    flex = model.nflex > 0  # flex elasticity and damping act through the passive forces
    can = {
        "springs": not off & int(flags.mjDSBL_SPRING)
        and (bool(np.any(model.jnt_stiffness)) or bool(np.any(model.tendon_stiffness)) or flex),
        "damping": not off & int(flags.mjDSBL_DAMPER)
        and (bool(np.any(model.dof_damping)) or bool(np.any(model.tendon_damping)) or flex),
        "fluid": model.opt.density > 0 or model.opt.viscosity > 0,
        "gravity_compensation": bool(np.any(model.body_gravcomp)),
        "actuators": model.nu > 0 and not off & int(flags.mjDSBL_ACTUATION),
    }
    return [(KIND[kind], array) for kind, array in _GENERALISED.items() if can[kind]]


def booked_dofs(model: mujoco.MjModel, kind: int) -> np.ndarray | None:
    """Per dof, 1 where the force of `kind` (a `generalised_forces` kind) is booked to it and
    0 where another kind holds it; None: every dof. Gravity compensation of a joint with
    `actuatorgravcomp` is in `qfrc_actuator` too (MuJoCo adds it there instead of to the
    passive force), so it is booked to the actuators only."""
    actuated: np.ndarray = np.asarray(model.jnt_actgravcomp, bool)[model.dof_jntid]
    if kind != KIND["gravity_compensation"] or not actuated.any():
        return None
    return np.where(actuated, 0.0, 1.0)


def other_constraints(model: mujoco.MjModel) -> bool:
    """Whether the model can have constraint rows besides contacts (limits, equalities,
    friction loss): their type is then copied at each step, to book their work."""
    return bool(
        model.neq
        or np.any(model.jnt_limited)
        or np.any(model.tendon_limited)
        or np.any(model.dof_frictionloss)
        or np.any(model.tendon_frictionloss)
    )


def constraint_work(
    power: np.ndarray, types: np.ndarray, steps: np.ndarray, nstep: int, timestep: float
) -> np.ndarray:
    """Work (J) per step and kind, (nstep, len(WORK_KINDS)), of constraint rows that are not
    contacts: each row's power (W), type and local step."""
    out = np.zeros((nstep, len(WORK_KINDS)))
    for mj_type, kind in _CONSTRAINTS.items():
        mine = types == mj_type
        if mine.any():
            out[:, kind] += timestep * np.bincount(steps[mine], power[mine], nstep)
    return out
