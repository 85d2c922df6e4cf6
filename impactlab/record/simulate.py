"""Simulate each run with `mj_step`, reading MuJoCo at every step; its rows go on chunk by chunk."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Generator, Iterable
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from impactlab.logs.checks import step_ns
from impactlab.logs.format import NOTHING_MOVES
from impactlab.record import budget
from impactlab.record.contacts import ContactTape, StepContacts, decode
from impactlab.record.episodes import Episode, Episodes
from impactlab.record.model import InstrumentedModel
from impactlab.record.mujoco_warnings import first_warning, quiet_mujoco
from impactlab.record.spec import Stop
from impactlab.record.stop import StopMonitor, Verdict
from impactlab.record.work import run_steps

CHUNK_SECONDS = 1.0
CHUNK_VALUES = 200_000  # per-step values a chunk holds (its buffers stay in the caches)
MIN_CHUNK_STEPS = 50
MAX_CHUNK_STEPS = 5_000
STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


def chunk_steps(timestep_s: float, values_per_step: int) -> int:
    """Steps per chunk: about CHUNK_SECONDS of simulated time, fewer for a large model (at
    most CHUNK_VALUES values of its state and forces), within bounds."""
    steps = min(round(CHUNK_SECONDS / timestep_s), CHUNK_VALUES // max(1, values_per_step))
    return int(np.clip(steps, MIN_CHUNK_STEPS, MAX_CHUNK_STEPS))


@dataclass(eq=False)  # hashable by identity: a key for the run's log while it is written
class RunRequest:
    """One run: the model, its time limit (s), stop rules and logging stride.

    `tag` is the caller's (e.g. the planned run); it comes back with every `Piece`.
    """

    inst: InstrumentedModel
    max_time: float
    stop: Stop | None = None
    log_every: int = 1
    tag: Any = None


@dataclass
class Ending:
    """How a run ended: the verdict, its warnings, rows logged, and its contact episodes."""

    verdict: Verdict
    warnings: list[str]
    logged: int
    t_end_ns: int
    episodes: list[Episode] = field(default_factory=list)

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
        work: the work each kind of force did from the run's start to each row, J,
            (nrow, len(budget.WORK_KINDS)).
        contacts: the contacts at the logged rows (`step`: the row's index in this piece).
        ending: set on the run's last piece.
        error: set when the run failed (nothing more comes for it).
        wall_s: wall time of the run so far.
    """

    request: RunRequest
    t_ns: np.ndarray
    sensordata: np.ndarray
    work: np.ndarray = field(default_factory=lambda: np.empty((0, len(budget.WORK_KINDS))))
    contacts: StepContacts | None = None
    ending: Ending | None = None
    error: str | None = None
    wall_s: float = 0.0


class _Run:
    """One run stepped chunk by chunk (see `simulate`)."""

    def __init__(self, request: RunRequest) -> None:
        self.request = request
        inst = request.inst
        model = self.model = inst.model
        self.data = mujoco.MjData(model)
        mujoco.mj_setState(model, self.data, inst.initial_state(), STATE)
        self.dt = float(model.opt.timestep)
        self.dt_ns = step_ns(self.dt)
        self.total = run_steps(request.max_time, self.dt)
        self.forces = budget.generalised_forces(model)
        self.booked = [budget.booked_dofs(model, kind) for kind, _ in self.forces]
        values = model.nsensordata + model.nq + model.nv * (2 + len(self.forces))
        self.chunk = chunk_steps(self.dt, values)
        self.rk4 = int(model.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_RK4)
        self.pyramidal = int(model.opt.cone) == int(mujoco.mjtCone.mjCONE_PYRAMIDAL)
        self.tape = ContactTape(model, self.data, types=budget.other_constraints(model))
        self.episodes = Episodes(inst, self.dt)
        self.monitor = StopMonitor(inst, request.stop, timestep=self.dt)
        self.work_done = np.zeros(len(budget.WORK_KINDS))
        self.v_last = self.data.qvel.copy()
        self.v_before = self.v_last  # RK4: the previous step's start velocity (`_steps`)
        self.step0 = 0
        self.logged = 0
        self.last_t_ns = 0
        self.started = time.perf_counter()
        n, nv = self.chunk, model.nv
        self.rows = np.empty((n, model.nsensordata))
        self.times = np.empty(n)
        self.vel = np.empty((n, nv))
        self.qpos = np.empty((n, model.nq)) if inst.joints is not None else None
        self.generalised = [np.empty((n, nv)) for _ in self.forces]
        # M qacc, qfrc_smooth and qfrc_constraint, per step with constraints (copies are the
        # cheapest operations per step: `_work` subtracts them per chunk)
        self.unbalanced = [np.zeros((n, nv)) for _ in range(3)]

    def next_piece(self) -> Piece:
        """Simulate the next chunk and return what it logs (the last one with the ending)."""
        n = min(self.chunk, self.total - self.step0)
        start = np.empty(mujoco.mj_stateSize(self.model, STATE))
        mujoco.mj_getState(self.model, self.data, start, STATE)
        warned = self.data.warning.number.tolist()
        self._steps(n)
        self.tape.check()
        v_start = np.vstack([self.v_last[None], self.vel[: n - 1]])
        contacts, work = self._work(n, v_start)
        saved = self.episodes.snapshot()
        released = self.episodes.update(contacts, self.rows[:n], self.step0)
        warning = self._warning(start, warned, n)
        limit = n if warning is None else warning.last_step + 1 - self.step0
        verdict = None
        if limit > 0:
            verdict = self.monitor.update(
                self.rows[:limit], self.step0, contacts, self.episodes, released, work[:limit]
            )
        verdict = verdict or warning
        if verdict is None and self.step0 + n >= self.total:
            verdict = Verdict(
                self.total - 1, "completed", f"time limit {self.request.max_time:g} s"
            )
        end = n if verdict is None else verdict.last_step - self.step0 + 1
        if end < n:  # the run stops inside the chunk: its contacts after the stop are not
            self.episodes.restore(saved)
            self.episodes.update(contacts.take(contacts.step < end), self.rows[:end], self.step0)
        piece = self._piece(end, verdict, work[:end], v_start[:end], contacts)
        self.work_done += work[:end].sum(axis=0)
        self.v_last = self.vel[n - 1].copy()
        self.step0 += n
        return piece

    def _steps(self, n: int) -> None:
        """Step n times, copying what MuJoCo computed for each step (hot loop)."""
        model, data, tape = self.model, self.data, self.tape
        rows, times, vel, qpos = self.rows, self.times, self.vel, self.qpos
        sensordata, qvel, qacc = data.sensordata, data.qvel, data.qacc
        smooth, constraint = data.qfrc_smooth, data.qfrc_constraint
        mass_acc, smooth_force, constraint_force = self.unbalanced
        for buf in self.unbalanced:
            buf[:n] = 0.0
        mul_m = mujoco.mj_mulM
        copies = [
            (buf, getattr(data, name))
            for buf, (_, name) in zip(self.generalised, self.forces, strict=True)
        ]
        tape.reset(n)
        step = mujoco.mj_step
        before = self.v_before  # RK4: the velocity at the previous step's start
        rk4 = self.rk4
        for i in range(n):
            if qpos is not None:
                times[i] = data.time
                qpos[i] = data.qpos
            if rk4:  # forces are read at the step's start, before the four stages
                mujoco.mj_checkPos(model, data)
                mujoco.mj_checkVel(model, data)
                mujoco.mj_forward(model, data)
                mujoco.mj_checkAcc(model, data)
            else:  # mj_step leaves the forces of its start state
                step(model, data)
            for buf, src in copies:
                buf[i] = src
            nefc = data.nefc
            if nefc:
                tape.add(i, after=not rk4)
                mul_m(model, data, mass_acc[i], qacc)
                smooth_force[i] = smooth
                constraint_force[i] = constraint
            if rk4:
                start = qvel.copy()
                mujoco.mj_RungeKutta(model, data, 4)
                if nefc:
                    tape.after_step(qvel, before)
                before = start
            rows[i] = sensordata
            vel[i] = qvel
        self.v_before = before

    def _work(self, n: int, v_start: np.ndarray) -> tuple[StepContacts, np.ndarray]:
        """The chunk's contacts, and the work of each kind of force during each of its steps,
        (n, kinds) J; the solver's is that of M qacc - qfrc_smooth - qfrc_constraint."""
        dt = self.dt
        v_mid = 0.5 * (v_start + self.vel[:n])
        work = np.zeros((n, len(budget.WORK_KINDS)))
        for buf, (kind, _), dofs in zip(self.generalised, self.forces, self.booked, strict=True):
            force = buf[:n] if dofs is None else buf[:n] * dofs
            work[:, kind] = dt * np.einsum("ij,ij->i", force, v_mid)
        contacts, power, in_contact = decode(self.tape, self.pyramidal)
        tape = self.tape
        row_step = np.repeat(np.arange(tape.nefc.size), tape.nefc)
        mass_acc, smooth, constraint = (buf[:n] for buf in self.unbalanced)
        work[:, budget.KIND["solver"]] = dt * np.einsum(
            "ij,ij->i", mass_acc - smooth - constraint, v_mid
        )
        normal, friction = budget.KIND["contact_normal"], budget.KIND["contact_friction"]
        work[:, normal] = dt * np.bincount(contacts.step, contacts.power_normal, n)
        work[:, friction] = dt * np.bincount(contacts.step, contacts.power_friction, n)
        if tape.types:
            rest = ~in_contact
            work += budget.constraint_work(
                power[rest], tape.type[: tape.nrow][rest], row_step[rest], n, dt
            )
        return contacts, work

    def _warning(self, start: np.ndarray, warned: list[int], n: int) -> Verdict | None:
        """The unstable verdict of a chunk in which MuJoCo raised a warning, else None."""
        if self.data.warning.number.tolist() == warned:
            return None
        found = first_warning(self.model, start, n)
        if found is None:
            return None
        step, text = found
        t = (self.step0 + step) * self.dt
        reason = f"MuJoCo warning at t = {t:.6g} s (step {self.step0 + step}): {text}"
        return Verdict(self.step0 + step - 1, "unstable", reason)

    def _piece(
        self,
        end: int,
        verdict: Verdict | None,
        work: np.ndarray,
        v_start: np.ndarray,
        contacts: StepContacts,
    ) -> Piece:
        """The rows of the chunk's first `end` steps that are logged: every `log_every`-th
        step from the run's start, and the step the run stops on."""
        every = self.request.log_every
        first = -self.step0 % every
        keep = np.arange(first, end, every, dtype=np.int64)
        if verdict is not None and end > 0 and (keep.size == 0 or keep[-1] != end - 1):
            keep = np.append(keep, end - 1)
        rows = self.rows[keep]
        joints = self.request.inst.joints
        if joints is not None and self.qpos is not None:
            states = np.hstack([self.times[keep, None], self.qpos[keep], v_start[keep]])
            rows = np.hstack([rows, joints.terms(states, rows)])
        # the work done before each logged step: the run's so far and the chunk's steps before
        done = self.work_done + np.vstack([np.zeros((1, work.shape[1])), np.cumsum(work, axis=0)])
        if keep.size == end:  # every step logged: the rows are the steps
            contacts = contacts.take(contacts.step < end)
        else:
            contacts = contacts.take(np.isin(contacts.step, keep))
            contacts = dataclasses.replace(contacts, step=np.searchsorted(keep, contacts.step))
        t_ns = (self.step0 + keep) * self.dt_ns
        if t_ns.size:
            self.logged += t_ns.size
            self.last_t_ns = int(t_ns[-1])
        ending = None
        if verdict is not None:
            ending = self._ending(verdict)
        wall = time.perf_counter() - self.started
        return Piece(self.request, t_ns, rows, done[keep], contacts, ending, wall_s=wall)

    def _ending(self, verdict: Verdict) -> Ending:
        stop = self.request.stop
        warnings = []
        episodes = self.episodes.finish(verdict.last_step)
        nbody = len(self.request.inst.bodies)
        touched = any(ep.side2 < nbody for ep in episodes)
        if stop is not None and stop.separation is not None and not touched:
            warnings.append(
                f"no contact between the bodies within {max(verdict.last_step, 0) * self.dt:g} s: "
                "the collision never happened, so 'after' equals 'before'"
            )
        if verdict.outcome == "unstable":
            warnings.append(f"unstable: {verdict.reason}")
        if not nbody:  # recorded as MuJoCo runs it: contacts, a constant energy
            warnings.append(NOTHING_MOVES)
        return Ending(verdict, warnings, self.logged, self.last_t_ns, episodes)


def simulate(requests: Iterable[RunRequest]) -> Generator[Piece, None, None]:
    """Simulate runs one after the other and yield their logged rows chunk by chunk.

    Each run steps with `mj_step` from its initial state (an RK4 run with its stages called
    one by one, to read the forces at the step's start); after every step the recorder
    copies MuJoCo's sensors, its contacts and constraint forces and the per-dof forces that
    can do work, so contacts, impacts and the energy budget are found at every step
    whatever the logging stride. Memory is bounded by the chunk.

    Yields:
        `Piece`s: each run's rows in time order, its last piece with its `ending`; a run
        that fails ends with a piece carrying `error`.
    """
    quiet_mujoco()
    for request in requests:
        try:
            run = _Run(request)
            while True:
                piece = run.next_piece()
                yield piece
                if piece.ending is not None:
                    break
        except Exception as exc:  # MuJoCo errors, e.g. a model it cannot step
            yield _failed(request, f"{type(exc).__name__}: {exc}")


def _failed(request: RunRequest, reason: str) -> Piece:
    return Piece(request, np.empty(0, np.int64), np.empty((0, 0)), error=reason)
