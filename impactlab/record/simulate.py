"""Simulate runs side by side in chunks of `mujoco.rollout`, stopping each on its own events.

Row i of a rollout's sensordata holds the sensors evaluated at the state *before* step i is
integrated, i.e. at simulation time i * timestep: that is the time every logged row carries.
Chunks continue from the last state; the solver's warm start restarts at each chunk boundary
(every CHUNK_SECONDS of simulated time), which is the only difference from a plain `mj_step`
loop (about 1e-12 in the state), and what makes a run independent of its batch.

A run logs every `log_every`-th step from step 0, and always the step it stops on (the apex
a stop rule waited for, the time limit), so the last logged row is the end of the run.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import mujoco
import numpy as np
from mujoco import rollout

from impactlab.record.model import InstrumentedModel
from impactlab.record.spec import Stop
from impactlab.record.stop import StopMonitor, Verdict

CHUNK_SECONDS = 1.0
MIN_CHUNK_STEPS = 1000
MAX_CHUNK_STEPS = 5_000


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


@dataclass
class RunRequest:
    """One run of a batch: the model, its time limit (s), stop rules and logging stride."""

    inst: InstrumentedModel
    max_time: float
    stop: Stop | None = None
    log_every: int = 1


@dataclass
class _Active:
    request: RunRequest
    monitor: StopMonitor
    total_steps: int
    state: np.ndarray
    kept: list[np.ndarray] = field(default_factory=list)
    kept_steps: list[np.ndarray] = field(default_factory=list)
    touched: bool = False
    verdict: Verdict | None = None


def simulate_batch(requests: list[RunRequest], *, threads: int | None = None) -> list[Trajectory]:
    """Run several models side by side with multi-threaded `mujoco.rollout`.

    The models must share MuJoCo's size signature (e.g. points of one sweep) and timestep.
    Every run advances in chunks of the same number of steps from step 0, and the solver's
    warm start restarts at each chunk, so a run's result does not depend on the batch it is
    in or on the number of threads.

    Args:
        requests: the runs.
        threads: rollout threads (default: one per core, at most one per run).

    Returns:
        One trajectory per request, in order.
    """
    model0 = requests[0].inst.model
    dt = float(model0.opt.timestep)
    chunk = int(np.clip(round(CHUNK_SECONDS / dt), MIN_CHUNK_STEPS, MAX_CHUNK_STEPS))
    nthread = max(1, min(threads or os.cpu_count() or 1, len(requests)))
    datas = [mujoco.MjData(model0) for _ in range(nthread)]
    active = [
        _Active(
            request=r,
            monitor=StopMonitor(r.inst, r.stop, timestep=dt),
            total_steps=max(1, math.ceil(r.max_time / dt - 1e-9)) + 1,
            state=r.inst.initial_state(),
        )
        for r in requests
    ]
    step0 = 0
    running = list(active)
    with rollout.Rollout(nthread=nthread if nthread > 1 else 0) as pool:
        while running:
            # never past the longest remaining time limit: the chunk boundaries of every run
            # stay at multiples of `chunk` from its start, whatever the batch
            nstep = min(chunk, max(a.total_steps for a in running) - step0)
            states, sens = pool.rollout(
                [a.request.inst.model for a in running],
                datas,
                np.stack([a.state for a in running]),
                nstep=nstep,
            )
            for i, a in enumerate(running):
                _advance(a, sens[i], states[i, -1], step0)
            running = [a for a in running if a.verdict is None]
            step0 += chunk
    return [_trajectory(a, dt) for a in active]


def _advance(a: _Active, rows: np.ndarray, last_state: np.ndarray, step0: int) -> None:
    """Feed one chunk of a run's rows to its stop rules and keep its logged rows."""
    n = min(rows.shape[0], a.total_steps - step0)
    rows = rows[:n]
    verdict = a.monitor.update(rows, step0)
    if verdict is None and step0 + n >= a.total_steps:
        verdict = Verdict(a.total_steps - 1, "completed", f"time limit {a.request.max_time:g} s")
    end = n if verdict is None else verdict.last_step - step0 + 1
    steps = np.arange(step0, step0 + end)
    keep = steps % a.request.log_every == 0
    if verdict is not None and end > 0:
        keep[-1] = True  # the step the run stops on
    a.kept.append(rows[:end][keep])
    a.kept_steps.append(steps[keep])
    if a.monitor.bodybody_cols:
        a.touched |= bool((rows[:end, a.monitor.bodybody_cols] > 0).any())
    a.state = last_state
    a.verdict = verdict


def _trajectory(a: _Active, dt: float) -> Trajectory:
    verdict = a.verdict
    assert verdict is not None
    stop = a.request.stop
    warnings = []
    if stop is not None and stop.separation is not None and not a.touched:
        warnings.append(
            f"no contact between the bodies within {verdict.last_step * dt:g} s: "
            "the collision never happened, so 'after' equals 'before'"
        )
    if verdict.outcome == "unstable":
        warnings.append(f"unstable: {verdict.reason}")
    rows = np.concatenate(a.kept) if a.kept else np.empty((0, a.request.inst.model.nsensordata))
    steps = np.concatenate(a.kept_steps) if a.kept_steps else np.empty(0, np.int64)
    return Trajectory(steps.astype(np.int64) * timestep_ns(dt), rows, verdict, warnings)
