"""MuJoCo's warnings: which step of a run raised the first one, and what it says."""

from __future__ import annotations

import mujoco
import numpy as np

from impactlab.mjcf.load import MESSAGES, quiet_mujoco

__all__ = ["MESSAGES", "first_warning", "quiet_mujoco"]


def first_warning(model: mujoco.MjModel, state: np.ndarray, nstep: int) -> tuple[int, str] | None:
    """Step a run from `state` (full physics) for up to `nstep` steps; find its first warning.

    Returns:
        The step (0 for the first) that raised it, and its name with MuJoCo's own text, e.g.
        "mjWARN_BADQVEL: Nan, Inf or huge value in QVEL at DOF 2. The simulation is
        unstable."; None when no step raises one.
    """
    quiet_mujoco()
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    for step in range(nstep):
        mujoco.mj_step(model, data)
        raised = [i for i, w in enumerate(data.warning) if w.number]
        if raised:
            kind = mujoco.mjtWarning(raised[0])
            text = mujoco.mju_warningText(kind, int(data.warning[raised[0]].lastinfo))
            return step, f"{kind.name}: {' '.join(text.split())}"
    return None
