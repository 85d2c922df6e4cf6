"""The rotor and spring energy the recorder logs equals MuJoCo's own, for every joint type."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from impactlab.record.joint_energy import joint_energy

SPRUNG = """
<mujoco><option gravity="0 0 0"/><worldbody>
  <body name="free" pos="0 0 1"><joint type="free" stiffness="3"/><geom type="box" size=".1 .2 .3"/></body>
  <body name="arm" pos="1 0 1">
    <joint name="hinge" type="hinge" axis="0 1 0" stiffness="5" springref="20" armature="0.3"/>
    <geom type="capsule" fromto="0 0 0 .5 0 0" size=".05"/>
    <body pos=".5 0 0">
      <joint name="slide" type="slide" axis="1 0 0" stiffness="7" armature="0.2"/>
      <geom type="sphere" size=".1"/>
      <body pos=".3 0 0">
        <joint name="ball" type="ball" stiffness="2" armature="0.1"/>
        <geom type="box" size=".1 .1 .1" pos=".1 0 0"/>
      </body>
    </body>
  </body>
</worldbody></mujoco>
"""


def _states(model: mujoco.MjModel, n: int) -> tuple[np.ndarray, mujoco.MjData]:
    rng = np.random.default_rng(0)
    data = mujoco.MjData(model)
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    states = np.empty((n, mujoco.mj_stateSize(model, kind)))
    for i in range(n):
        data.qpos[:] = model.qpos0 + rng.normal(0.0, 0.8, model.nq)
        mujoco.mj_normalizeQuat(model, data.qpos)
        data.qvel[:] = rng.normal(0.0, 2.0, model.nv)
        mujoco.mj_getState(model, data, states[i], kind)
    return states, data


def _mujoco_energy(model: mujoco.MjModel, state: np.ndarray) -> tuple[float, float]:
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    mujoco.mj_forward(model, data)
    mujoco.mj_energyPos(model, data)
    mujoco.mj_energyVel(model, data)
    return float(data.energy[0]), float(data.energy[1])


def test_spring_and_rotor_energy_equal_mujocos():
    """Without gravity MuJoCo's potential energy is the springs' alone; its kinetic energy
    less that of the same model without armature is the rotors'."""
    model = mujoco.MjModel.from_xml_string(SPRUNG)
    bare = mujoco.MjModel.from_xml_string(SPRUNG)
    bare.dof_armature[:] = 0.0
    states, _ = _states(model, 20)
    terms = joint_energy(model, [])
    assert terms is not None
    got = terms.terms(states, np.empty((len(states), 0)))
    for row, (rotor, springs) in zip(states, got, strict=True):
        potential, kinetic = _mujoco_energy(model, row)
        _, kinetic_bare = _mujoco_energy(bare, row)
        assert springs == pytest.approx(potential, rel=1e-9, abs=1e-12)
        assert rotor == pytest.approx(kinetic - kinetic_bare, rel=1e-9, abs=1e-12)
    assert got[:, 1].min() > 0.1 and got[:, 0].min() > 0.0  # every state has both terms


def test_no_springs_no_rotors_no_terms():
    model = mujoco.MjModel.from_xml_string(SPRUNG)
    model.jnt_stiffness[:] = 0.0
    model.dof_armature[:] = 0.0
    assert joint_energy(model, []) is None
    model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_SPRING)
    model.dof_armature[0] = 1.0
    terms = joint_energy(model, [])
    assert terms is not None and terms.hinges.size == 0 and terms.balls.size == 0
