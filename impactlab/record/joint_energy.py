"""The energy MuJoCo counts in joints rather than bodies: rotor inertia and springs."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

TENDON_SENSOR = "tendon_length:"
"""Name (after the recorder's prefix) of the sensor that reads a sprung tendon's length."""


@dataclass(frozen=True)
class JointEnergy:
    """Where a model's rotor inertia and springs are, to evaluate them on states.

    `tendon_adrs`: sensordata columns of the sprung tendons' lengths.
    """

    nq: int
    armature: np.ndarray  # (nv,)
    hinges: np.ndarray  # qpos addresses of sprung hinge and slide joints (and free positions)
    hinge_k: np.ndarray
    balls: np.ndarray  # qpos addresses of sprung ball (or free-joint) orientations
    ball_k: np.ndarray
    qpos_spring: np.ndarray  # (nq,)
    tendon_adrs: np.ndarray
    tendon_k: np.ndarray
    tendon_range: np.ndarray  # (ntendon, 2)

    def terms(self, states: np.ndarray, sensordata: np.ndarray) -> np.ndarray:
        """Rotor kinetic and spring potential energy, J, (n, 2), of full-physics states
        (n, nstate: time, qpos, qvel, ...) and the sensordata rows at the same steps."""
        qpos = states[:, 1 : 1 + self.nq]
        qvel = states[:, 1 + self.nq : 1 + self.nq + self.armature.size]
        kinetic = 0.5 * (qvel**2) @ self.armature
        potential = np.zeros(states.shape[0])
        if self.hinges.size:
            d = qpos[:, self.hinges] - self.qpos_spring[self.hinges]
            potential += 0.5 * (d**2) @ self.hinge_k
        for adr, k in zip(self.balls, self.ball_k, strict=True):
            angle = rotation_vector(qpos[:, adr : adr + 4], self.qpos_spring[adr : adr + 4])
            potential += 0.5 * k * (angle**2).sum(axis=1)
        if self.tendon_adrs.size:
            length = sensordata[:, self.tendon_adrs]
            lo, hi = self.tendon_range[:, 0], self.tendon_range[:, 1]
            d = np.where(length > hi, hi - length, np.where(length < lo, lo - length, 0.0))
            potential += 0.5 * (d**2) @ self.tendon_k
        return np.stack([kinetic, potential], axis=1)


def rotation_vector(q: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """The rotation vector (axis times angle, rad) that turns `ref` into each quaternion of
    `q` (n, 4; w first), as MuJoCo's mju_subQuat: log(conj(ref) q), angle in [-pi, pi]."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    ref = ref / np.linalg.norm(ref)
    w0, v0 = ref[0], -ref[1:]
    w = w0 * q[:, 0] - q[:, 1:] @ v0
    v = w0 * q[:, 1:] + q[:, :1] * v0 + np.cross(v0, q[:, 1:])
    sin = np.linalg.norm(v, axis=1)
    angle = 2.0 * np.arctan2(sin, w)
    angle = np.where(angle > np.pi, angle - 2.0 * np.pi, angle)
    scale = np.divide(angle, sin, out=np.full_like(angle, 2.0), where=sin > 1e-15)
    rotation: np.ndarray = v * scale[:, None]
    return rotation


def sprung_tendons(model: mujoco.MjModel) -> list[int]:
    """Tendons whose spring acts (stiffness > 0, springs enabled)."""
    if _springs_disabled(model):
        return []
    return [t for t in range(model.ntendon) if model.tendon_stiffness[t] > 0]


def joint_energy(model: mujoco.MjModel, tendon_adrs: list[int]) -> JointEnergy | None:
    """The model's rotor and spring terms, or None when it has neither (they are zero)."""
    springs = not _springs_disabled(model)
    hinge, ball = [], []
    for j in range(model.njnt):
        k = float(model.jnt_stiffness[j])
        if not springs or k <= 0:
            continue
        adr, kind = int(model.jnt_qposadr[j]), int(model.jnt_type[j])
        if kind in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
            hinge.append((adr, k))
        elif kind == int(mujoco.mjtJoint.mjJNT_BALL):
            ball.append((adr, k))
        else:  # a free joint: its position's three coordinates, then its orientation
            hinge += [(adr, k), (adr + 1, k), (adr + 2, k)]
            ball.append((adr + 3, k))
    tendons = sprung_tendons(model)
    armature = np.asarray(model.dof_armature, dtype=float).copy()
    if not (hinge or ball or tendons or np.any(armature != 0)):
        return None

    def split(items: list[tuple[int, float]]) -> tuple[np.ndarray, np.ndarray]:
        return np.array([a for a, _ in items], np.int64), np.array([k for _, k in items])

    (h, hk), (b, bk) = split(hinge), split(ball)
    return JointEnergy(
        nq=model.nq,
        armature=armature,
        hinges=h,
        hinge_k=hk,
        balls=b,
        ball_k=bk,
        qpos_spring=np.asarray(model.qpos_spring, dtype=float).copy(),
        tendon_adrs=np.array(tendon_adrs, np.int64),
        tendon_k=np.array([model.tendon_stiffness[t] for t in tendons]),
        tendon_range=np.array([model.tendon_lengthspring[t] for t in tendons]).reshape(-1, 2),
    )


def _springs_disabled(model: mujoco.MjModel) -> bool:
    return bool(int(model.opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_SPRING))
