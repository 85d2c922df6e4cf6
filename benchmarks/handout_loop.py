"""The handout's loop, the baseline of recording: MuJoCo models stepped one after the other,
each step's state copied, nothing logged.

`cases.handout_loop` calls `step_all` in process; run as a program, `python handout_loop.py
FOLDER STEPS` steps FOLDER's MJCF files, the loop as a whole process (`cases.bare_loop_argv`).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import mujoco
import numpy as np


def step_all(models: Sequence[mujoco.MjModel], steps: int) -> None:
    """Step each model `steps` times from its first keyframe, copying qpos and qvel."""
    for model in models:
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, 0)
        qpos, qvel = [], []
        for _ in range(steps):
            mujoco.mj_step(model, data)
            qpos.append(data.qpos.copy())
            qvel.append(data.qvel.copy())
        np.asarray(qpos)


if __name__ == "__main__":
    folder, steps = Path(sys.argv[1]), int(sys.argv[2])
    step_all([mujoco.MjModel.from_xml_path(str(p)) for p in sorted(folder.glob("*.xml"))], steps)
