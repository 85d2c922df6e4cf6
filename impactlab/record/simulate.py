"""Simulate runs side by side in chunks of `mujoco.rollout`, stopping each on its own events.

Row i of a rollout's sensordata holds the sensors evaluated at the state *before* step i is
integrated, i.e. at simulation time i * timestep: that is the time every logged row carries.
Chunks continue from the last state; the solver's warm start restarts at each chunk boundary
(every CHUNK_SECONDS of simulated time), which is the only difference from a plain `mj_step`
loop (about 1e-12 in the state), and what makes a run independent of its batch.

A run logs every `log_every`-th step from step 0, and always the step it stops on (the apex
a stop rule waited for, the time limit), so the last logged row is the end of the run.
Rows are handed on chunk by chunk (`simulate`), never gathered: memory per run is bounded by
the chunk, whatever the time limit or the timestep. MuJoCo's warnings (a state it had to
reset, too many contacts, ...) stop a run as unstable: `mujoco.rollout` stops stepping a run
as soon as one is raised and repeats its last state, which the time column shows; the run's
chunk is then stepped again alone to name the warning (`impactlab.record.mujoco_warnings`).
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
import time
from collections.abc import Generator, Iterable
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
from mujoco import rollout

from impactlab.record.contact_work import ContactWork
from impactlab.record.model import InstrumentedModel
from impactlab.record.mujoco_warnings import first_warning, quiet_mujoco
from impactlab.record.spec import Stop
from impactlab.record.stop import StopMonitor, Verdict
from impactlab.record.work import run_steps

CHUNK_SECONDS = 1.0
MIN_CHUNK_STEPS = 1000
MAX_CHUNK_STEPS = 5_000
STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS  # its first value is the simulation time


def timestep_ns(timestep_s: float) -> int:
    """The timestep in integer nanoseconds (log times are step index times this)."""
    return max(1, round(timestep_s * 1e9))


def chunk_steps(timestep_s: float) -> int:
    """Steps per rollout chunk: about CHUNK_SECONDS of simulated time, within bounds."""
    return int(np.clip(round(CHUNK_SECONDS / timestep_s), MIN_CHUNK_STEPS, MAX_CHUNK_STEPS))


@dataclass(eq=False)  # hashable by identity: a key for the run's log while it is written
class RunRequest:
    """One run of a batch: the model, its time limit (s), stop rules and logging stride.

    `tag` is the caller's (e.g. the planned run); it comes back with every `Piece`.
    """

    inst: InstrumentedModel
    max_time: float
    stop: Stop | None = None
    log_every: int = 1
    tag: Any = None


@dataclass
class Ending:
    """How a run ended: the verdict, its warnings, steps simulated and rows logged, and each
    contact pair's contacts with their work (`impactlab.record.contact_work`)."""

    verdict: Verdict
    warnings: list[str]
    logged: int
    t_end_ns: int
    contact_work: list[np.ndarray] = field(default_factory=list)

    @property
    def steps(self) -> int:
        return self.verdict.last_step + 1


@dataclass
class Piece:
    """What `simulate` hands on: a run's next logged rows, or its end, or its failure.

    Attributes:
        request: the run.
        t_ns: simulation time of each logged row, integer ns, (nrow,).
        sensordata: the recorder's sensors at those times, (nrow, nsensordata), then (for a
            model with rotor inertia or springs) their energy, 2 columns (`JointEnergy`).
        ending: set on the run's last piece.
        error: set when the run's batch failed (nothing more comes for it).
        wall_s: wall time of the run's batch so far, shared among its runs.
    """

    request: RunRequest
    t_ns: np.ndarray
    sensordata: np.ndarray
    ending: Ending | None = None
    error: str | None = None
    wall_s: float = 0.0


@dataclass
class _Active:
    request: RunRequest
    monitor: StopMonitor
    work: ContactWork
    total_steps: int
    state: np.ndarray
    touched: bool = False
    verdict: Verdict | None = None
    logged: int = 0
    last_t_ns: int = 0


class _Batch:
    """Runs sharing MuJoCo's size signature and timestep, stepped chunk by chunk together."""

    def __init__(self, requests: list[RunRequest], threads: int | None) -> None:
        model0 = requests[0].inst.model
        self.dt = float(model0.opt.timestep)
        self.dt_ns = timestep_ns(self.dt)
        self.chunk = chunk_steps(self.dt)
        self.nthread = max(1, min(threads or os.cpu_count() or 1, len(requests)))
        self.datas = [mujoco.MjData(model0) for _ in range(self.nthread)]
        self.active = [
            _Active(
                request=r,
                monitor=StopMonitor(r.inst, r.stop, timestep=self.dt),
                work=ContactWork(r.inst, self.dt),
                total_steps=run_steps(r.max_time, self.dt),
                state=r.inst.initial_state(),
            )
            for r in requests
        ]
        self.running = list(self.active)
        self.step0 = 0
        self.started = time.perf_counter()
        self.pool = rollout.Rollout(nthread=self.nthread if self.nthread > 1 else 0)

    def rollout(self) -> tuple[np.ndarray, np.ndarray, int]:
        """Step every running run through the next chunk (plus one step that shows a warning
        raised in the chunk's last step). Returns states, sensordata and the chunk's steps."""
        # never past the longest remaining time limit: the chunk boundaries of every run
        # stay at multiples of `chunk` from its start, whatever the batch
        nstep = min(self.chunk, max(a.total_steps for a in self.running) - self.step0)
        states, sens = self.pool.rollout(
            [a.request.inst.model for a in self.running],
            self.datas,
            np.stack([a.state for a in self.running]),
            nstep=nstep + 1,
        )
        return states, sens, nstep

    def take(self, states: np.ndarray, sens: np.ndarray, nstep: int) -> list[Piece]:
        """Apply a chunk's rows to each running run's stop rules; the pieces to hand on."""
        pieces = []
        wall = (time.perf_counter() - self.started) / len(self.active)
        for i, a in enumerate(self.running):
            first_state = a.state
            rows, steps = _advance(
                a, sens[i, :nstep], states[i, nstep - 1], self.step0, states[i, :, 0]
            )
            joints = a.request.inst.joints
            if joints is not None:  # its rotor and spring energy, as two more columns
                local = steps - self.step0  # the state before step k: after step k - 1
                before = states[i, np.maximum(local - 1, 0)]
                before[local == 0] = first_state
                rows = np.hstack([rows, joints.terms(before, rows)])
            t_ns = steps * self.dt_ns
            if t_ns.size:
                a.logged += t_ns.size
                a.last_t_ns = int(t_ns[-1])
            ending = None if a.verdict is None else _ending(a, self.dt)
            pieces.append(Piece(a.request, t_ns, rows, ending, wall_s=wall))
        self.running = [a for a in self.running if a.verdict is None]
        self.step0 += self.chunk
        return pieces

    def fail(self, reason: str) -> list[Piece]:
        """The pieces that end every running run of the batch as failed."""
        self.running, failed = [], self.running
        return [_failed(a.request, reason) for a in failed]

    def close(self) -> None:
        self.pool.close()


def _advance(
    a: _Active,
    rows: np.ndarray,
    last_state: np.ndarray,
    step0: int,
    times: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Feed one chunk of a run's rows to its stop rules; returns the rows it logs and their
    global step indices: every `log_every`-th step of the chunk up to its stop, and the step
    the run stops on ((n, nsensordata), (n,)).

    `times` is the simulation time after each step of the rollout, (nstep + 1,) (see
    `_warning`).
    """
    n = min(rows.shape[0], a.total_steps - step0)
    warning = _warning(a, times[: n + 1], step0) if times is not None else None
    limit = n if warning is None else warning.last_step + 1 - step0
    verdict = a.monitor.update(rows[:limit], step0) if limit > 0 else None
    verdict = verdict or warning
    if verdict is None and step0 + n >= a.total_steps:
        verdict = Verdict(a.total_steps - 1, "completed", f"time limit {a.request.max_time:g} s")
    end = n if verdict is None else verdict.last_step - step0 + 1
    a.work.update(rows[:end], step0)
    if a.monitor.bodybody_cols:
        a.touched |= bool((rows[:end, a.monitor.bodybody_cols] > 0).any())
    a.state = last_state
    a.verdict = verdict
    every = a.request.log_every
    first = -step0 % every  # the first row of the chunk whose global step is logged
    keep = np.arange(first, end, every, dtype=np.int64)
    if verdict is not None and end > 0 and (keep.size == 0 or keep[-1] != end - 1):
        keep = np.append(keep, end - 1)  # the step the run stops on
        return rows[keep], step0 + keep
    return rows[first:end:every], step0 + keep


def _warning(a: _Active, times: np.ndarray, step0: int) -> Verdict | None:
    """The unstable verdict of a run whose chunk raised a MuJoCo warning, else None.

    After a warning, `mujoco.rollout` repeats the run's last state for the rest of the chunk,
    and a warning that reset the state also reset its time: either way the time after some
    step is not the chunk's start time plus the steps taken. The chunk is then stepped again
    alone to find the step that raised the warning and to name it (the rows from that step
    on are MuJoCo's reset or repeated state, not the run's).
    """
    dt = float(a.request.inst.model.opt.timestep)
    expected = a.state[0] + dt * np.arange(1, times.size + 1)
    bad = _first(np.abs(times - expected) > 0.5 * dt)
    if bad is None:
        return None
    found = first_warning(a.request.inst.model, a.state, bad + 1)
    if found is None:
        step, text = max(bad - 1, 0), "MuJoCo stopped the rollout (a warning not raised again)"
    else:
        step, text = found
    if step >= times.size - 1:  # in the step after the run's last: not the run's
        return None
    t = (step0 + step) * dt
    reason = f"MuJoCo warning at t = {t:.6g} s (step {step0 + step}): {text}"
    return Verdict(step0 + step - 1, "unstable", reason)


def _first(mask: np.ndarray) -> int | None:
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None


def _ending(a: _Active, dt: float) -> Ending:
    verdict = a.verdict
    assert verdict is not None
    stop = a.request.stop
    warnings = []
    if stop is not None and stop.separation is not None and not a.touched:
        warnings.append(
            f"no contact between the bodies within {max(verdict.last_step, 0) * dt:g} s: "
            "the collision never happened, so 'after' equals 'before'"
        )
    if verdict.outcome == "unstable":
        warnings.append(f"unstable: {verdict.reason}")
    return Ending(verdict, warnings, a.logged, a.last_t_ns, a.work.finish())


def simulate(
    batches: Iterable[list[RunRequest]], *, threads: int | None = None, ahead: int = 2
) -> Generator[Piece, None, None]:
    """Simulate batches of runs and yield their logged rows chunk by chunk, as they come.

    The runs of a batch must share MuJoCo's size signature (e.g. points of one sweep) and
    timestep. Every run advances in chunks of the same number of steps from step 0, and the
    solver's warm start restarts at each chunk, so a run's rows do not depend on the batch it
    is in or on the number of threads. The simulation runs on its own thread (MuJoCo releases
    the GIL while it steps), up to `ahead` chunks ahead of the caller: while the caller
    handles a chunk's pieces, the next ones simulate and the next batch is built. Closing the
    generator waits for at most the chunk being simulated.

    Args:
        batches: lists of runs (consumed lazily on the simulation thread, one batch ahead).
        threads: rollout threads (default: one per core, at most one per run).
        ahead: chunks the simulation may run ahead of the caller (bounds the memory).

    Yields:
        `Piece`s: each run's rows in time order, its last piece with its `ending`; a batch
        whose simulation fails ends each of its runs with a piece carrying `error`.

    Raises:
        Whatever iterating `batches` raises, on the caller's thread.
    """
    quiet_mujoco()
    out: queue.Queue[list[Piece] | BaseException | None] = queue.Queue(maxsize=max(1, ahead))
    stop = threading.Event()

    def put(item: list[Piece] | BaseException | None) -> bool:
        while not stop.is_set():
            with contextlib.suppress(queue.Full):
                out.put(item, timeout=0.05)
                return True
        return False

    def produce() -> None:
        try:
            with contextlib.closing(_chunks(batches, threads, stop)) as chunks:
                for pieces in chunks:
                    if not put(pieces):
                        return
            put(None)
        except BaseException as exc:  # handed to the caller's thread
            put(exc)

    producer = threading.Thread(target=produce, name="impactlab-sim", daemon=True)
    producer.start()
    try:
        while (item := out.get()) is not None:
            if isinstance(item, BaseException):
                raise item
            yield from item
    finally:
        stop.set()
        producer.join()


def _chunks(
    batches: Iterable[list[RunRequest]], threads: int | None, stop: threading.Event
) -> Generator[list[Piece], None, None]:
    """Each chunk's pieces of every batch in turn, until `stop` is set."""
    for requests in batches:
        if not requests:
            continue
        try:
            batch = _Batch(requests, threads)
        except Exception as exc:
            yield [_failed(r, f"{type(exc).__name__}: {exc}") for r in requests]
            continue
        try:
            while batch.running and not stop.is_set():
                try:
                    pieces = batch.take(*batch.rollout())
                except Exception as exc:  # MuJoCo errors, e.g. a model it cannot step
                    pieces = batch.fail(f"{type(exc).__name__}: {exc}")
                yield pieces
        finally:
            batch.close()
        if stop.is_set():
            return


def _failed(request: RunRequest, reason: str) -> Piece:
    return Piece(request, np.empty(0, np.int64), np.empty((0, 0)), error=reason)
