"""Simulate one run in chunks of `mujoco.rollout`, stopping on events, keeping the logged rows.

Row i of a rollout's sensordata holds the sensors evaluated at the state *before* step i is
integrated, i.e. at simulation time i * timestep: that is the time every logged row carries.
Chunks continue from the last state and the solver's warm start, so the result is bitwise the
same as a plain `mj_step` loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
from mujoco import rollout

from impactlab.record.model import InstrumentedModel
from impactlab.record.spec import Stop
from impactlab.record.stop import StopMonitor, Verdict

CHUNK_SECONDS = 0.25
MIN_CHUNK_STEPS = 256
MAX_CHUNK_STEPS = 20_000


@dataclass
class Trajectory:
    """The logged rows of one run.

    Attributes:
        t_ns: simulation time of each logged row, integer ns, (nrow,).
        sensordata: the recorder's sensors at those times, (nrow, nsensordata).
        verdict: why and when the run stopped.
        warnings: sentences for the log and the console.
    """

    t_ns: np.ndarray
    sensordata: np.ndarray
    verdict: Verdict
    warnings: list[str] = field(default_factory=list)


def timestep_ns(timestep_s: float) -> int:
    """The timestep in integer nanoseconds (log times are step index times this)."""
    return max(1, round(timestep_s * 1e9))


def simulate(
    inst: InstrumentedModel, *, max_time: float, stop: Stop | None = None, log_every: int = 1
) -> Trajectory:
    """Run the model from its initial state until a stop rule fires or `max_time` (s) passes.

    Args:
        inst: the instrumented model.
        max_time: time limit in s.
        stop: the spec's stop rules (None: run for `max_time`).
        log_every: keep every n-th step.

    Returns:
        The kept rows, the verdict and any warnings.
    """
    model = inst.model
    dt = float(model.opt.timestep)
    total_steps = max(1, math.ceil(max_time / dt - 1e-9)) + 1  # rows for t = 0 .. max_time
    chunk = int(np.clip(round(CHUNK_SECONDS / dt), MIN_CHUNK_STEPS, MAX_CHUNK_STEPS))
    monitor = StopMonitor(inst, stop, timestep=dt)
    data = mujoco.MjData(model)
    state = inst.initial_state()[None]
    warmstart = None
    kept: list[np.ndarray] = []
    step0 = 0
    verdict: Verdict | None = None
    bodybody_touched = False
    while step0 < total_steps:
        n = min(chunk, total_steps - step0)
        states, sens = rollout.rollout(model, data, state, nstep=n, initial_warmstart=warmstart)
        rows = sens[0]
        verdict = monitor.update(rows, step0)
        end = n if verdict is None else verdict.last_step - step0 + 1
        steps = np.arange(step0, step0 + end)
        kept.append(rows[:end][steps % log_every == 0])
        if monitor.bodybody_cols:
            bodybody_touched |= bool((rows[:end, monitor.bodybody_cols] > 0).any())
        if verdict is not None:
            break
        state, warmstart = states[:, -1], data.qacc_warmstart[None].copy()
        step0 += n
    if verdict is None:
        verdict = Verdict(total_steps - 1, "completed", f"time limit {max_time:g} s")
    warnings = []
    if stop is not None and stop.separation is not None and not bodybody_touched:
        warnings.append(
            f"no contact between the bodies within {verdict.last_step * dt:g} s: "
            "the collision never happened, so 'after' equals 'before'"
        )
    if verdict.outcome == "unstable":
        warnings.append(f"unstable: {verdict.reason}")
    rows = np.concatenate(kept) if kept else np.empty((0, model.nsensordata))
    steps = np.arange(0, verdict.last_step + 1, log_every, dtype=np.int64)[: rows.shape[0]]
    return Trajectory(steps * timestep_ns(dt), rows, verdict, warnings)
