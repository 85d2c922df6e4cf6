"""Stop rules evaluated on every simulated step of a chunk, vectorised, with state carried on."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from impactlab.physics import min_impact_speed
from impactlab.record.budget import WORK_KINDS
from impactlab.record.contacts import StepContacts
from impactlab.record.geometry import can_collide, gravity, up_vector
from impactlab.record.model import InstrumentedModel
from impactlab.record.spec import Stop

if TYPE_CHECKING:
    from impactlab.record.episodes import Episode, Episodes


@dataclass(frozen=True)
class Chunk:
    """What a chunk gives the rules: every step's sensordata rows from `step0`, the
    contacts (local steps) and their parties, the episodes released in it, and each step's
    work per kind of force (J)."""

    rows: np.ndarray
    step0: int
    contacts: StepContacts
    sides: tuple[np.ndarray, np.ndarray]
    released: list[Episode]
    work: np.ndarray


@dataclass
class Verdict:
    """Why a run stopped: the last step kept, the outcome and a sentence for people."""

    last_step: int
    outcome: str  # "completed" or "unstable"
    reason: str


def _first(mask: np.ndarray) -> int | None:
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None


def _touching(chunk: Chunk, contacts: np.ndarray) -> np.ndarray:
    """Per step of the chunk, whether any of the chosen contacts (a mask) is at it."""
    touching = np.zeros(chunk.rows.shape[0], bool)
    touching[chunk.contacts.step[contacts]] = True
    return touching


def _finite(chunk: Chunk) -> Verdict | None:
    """Unstable when a row holds a non-finite value: the step before it is the last kept."""
    bad = _first(~np.isfinite(chunk.rows).all(axis=1))
    if bad is None:
        return None
    step = chunk.step0 + bad
    return Verdict(step - 1, "unstable", f"state became non-finite at step {step}")


@dataclass
class _Bounces:
    """Stop at the apex after the N-th bounce of every free body that lands on the ground.

    A bounce is an episode of the body with a ground surface that arrived at an impact speed
    (`physics.min_impact_speed`) and was released: the body stayed apart for
    `physics.MIN_FLIGHT_STEPS` steps (the analysis counts the same episodes). The apex is the
    first step from then on whose velocity along -gravity (`vel_adr`: the body's linear
    velocity) is not positive and where the body touches no surface.
    """

    n: int
    bodies: list[int]  # party ids of the free bodies that can land on a surface
    vel_adr: list[int]
    surfaces: set[int]
    up: np.ndarray
    v_min: float
    count: dict[int, int] = field(default_factory=dict)
    since: dict[int, int] = field(default_factory=dict)  # global step the N-th is certain
    done: dict[int, int] = field(default_factory=dict)

    def update(self, chunk: Chunk) -> Verdict | None:
        rows, step0 = chunk.rows, chunk.step0
        for ep in chunk.released:
            if ep.side1 in self.bodies and ep.side2 in self.surfaces and -ep.v_in >= self.v_min:
                self.count[ep.side1] = self.count.get(ep.side1, 0) + 1
                if self.count[ep.side1] == self.n:
                    self.since[ep.side1] = ep.confirmed
        p1, p2 = chunk.sides
        for body, adr in zip(self.bodies, self.vel_adr, strict=True):
            if body in self.done or body not in self.since:
                continue
            mine = ((p1 == body) & np.isin(p2, list(self.surfaces))) | (
                (p2 == body) & np.isin(p1, list(self.surfaces))
            )
            touching = _touching(chunk, mine)
            v_up = rows[:, adr : adr + 3] @ self.up
            later = np.arange(rows.shape[0]) + step0 >= self.since[body]
            apex = _first(later & ~touching & (v_up <= 0.0))
            if apex is not None:
                self.done[body] = step0 + apex
        if self.bodies and all(b in self.done for b in self.bodies):
            last = max(self.done.values())
            return Verdict(last, "completed", f"apex after bounce {self.n}")
        return None


@dataclass
class _AtRest:
    """Stop once every body is slower than `speed` for `steps` consecutive steps."""

    speed: float
    steps: int
    vel_cols: list[int]
    run: int = 0

    def update(self, chunk: Chunk) -> Verdict | None:
        rows, step0 = chunk.rows, chunk.step0
        slow = np.ones(rows.shape[0], bool)  # a model where nothing moves is at rest
        for c in self.vel_cols:
            slow &= np.linalg.norm(rows[:, c : c + 3], axis=1) < self.speed
        # length of the run of slow steps ending at each row, continuing the previous chunk's
        idx = np.arange(slow.size)
        last_break = np.maximum.accumulate(np.where(slow, -1 - self.run, idx))
        length = idx - last_break
        hit = _first(length >= self.steps)
        self.run = int(length[-1])
        if hit is None:
            return None
        return Verdict(step0 + hit, "completed", "bodies at rest")


@dataclass
class _Separated:
    """Stop once two bodies have touched and their surfaces are `gap_m` apart again.

    `gap_cols`: per pair of bodies, the columns of MuJoCo's distance sensors between their
    geoms (the gap is the smallest); `nbody`: parties below it are rigid bodies.
    """

    gap_m: float
    gap_cols: list[list[int]]
    nbody: int
    touched: bool = False

    def update(self, chunk: Chunk) -> Verdict | None:
        rows, step0 = chunk.rows, chunk.step0
        p1, p2 = chunk.sides
        between = (p1 < self.nbody) & (p2 < self.nbody) & (p1 != p2)
        touching = _touching(chunk, between)
        seen = self.touched | (np.cumsum(touching) > 0)
        self.touched = bool(seen[-1])
        gaps = np.stack([rows[:, cols].min(axis=1) for cols in self.gap_cols]).min(axis=0)
        hit = _first(seen & ~touching & (gaps >= self.gap_m))
        if hit is None:
            return None
        return Verdict(step0 + hit, "completed", f"bodies separated by {self.gap_m:g} m")


@dataclass
class _Residual:
    """Unstable when the integrator makes energy: in one step, the residual (the change of
    the budget's energy, MuJoCo's kinetic energy plus the bodies' gravitational potential
    energy, minus the work of every other force, `impactlab.record.budget`) rises above its
    highest so far by more than `fraction` of the energy in play so far (the largest kinetic
    energy before the step, potential-energy swing before it, or magnitude of any force's
    work up to its end; at least `in_play` as given). A bounded drift (semi-implicit Euler's) moves
    the residual by a small part of that energy per step, a blow-up by a large one; a
    residual that comes back after a drop (an impulse's work booked a step early) makes no
    new energy, and energy a force's work explains, however large, leaves it unchanged."""

    kinetic_adr: int
    pos_adr: list[int]
    weights: np.ndarray  # per body, -mass * gravity (3,): its potential energy is w . x
    fraction: float
    timestep: float
    in_play: float  # the energy in play before the next step, J (given: the floor)
    start: float | None = None
    highest: float = 0.0  # the highest residual so far
    potential: tuple[float, float] = (math.inf, -math.inf)  # lowest, highest so far
    work_done: np.ndarray = field(default_factory=lambda: np.zeros(len(WORK_KINDS)))  # J

    def update(self, chunk: Chunk) -> Verdict | None:
        rows, work = chunk.rows, chunk.work
        potential = np.zeros(rows.shape[0])
        for a, w in zip(self.pos_adr, self.weights, strict=True):
            potential += rows[:, a : a + 3] @ w
        kinetic = rows[:, self.kinetic_adr]
        energy = kinetic + potential
        if self.start is None:
            self.start = float(energy[0])
        # per step i, the work done before it (`done`) and the energy in play up to it
        done = self.work_done + np.vstack([np.zeros((1, work.shape[1])), np.cumsum(work, 0)])
        residual = energy - self.start - done[:-1].sum(axis=1)
        low = np.minimum.accumulate(np.r_[self.potential[0], potential])
        high = np.maximum.accumulate(np.r_[self.potential[1], potential])
        before = np.maximum(np.r_[self.in_play, kinetic], high - low)
        works = np.abs(done).max(axis=1)
        in_play = np.maximum.accumulate(np.maximum(before, works))
        highest = np.maximum.accumulate(np.r_[self.highest, residual])
        growth = residual - highest[:-1]
        bound = self.fraction * in_play[:-1]
        self.work_done = done[-1]
        self.highest, self.in_play = float(highest[-1]), float(in_play[-1])
        self.potential = (float(low[-1]), float(high[-1]))
        bad = _first(growth > bound)
        if bad is None:
            return None
        t = (chunk.step0 + bad) * self.timestep
        reason = (
            f"energy grew by {growth[bad]:.4g} J in one step that no force explains (bound "
            f"{self.fraction:g} x {bound[bad] / self.fraction:.4g} J, the energy in play) at "
            f"t = {t:.6g} s"
        )
        return Verdict(chunk.step0 + bad, "unstable", reason)


@dataclass
class _Penetration:
    """Unstable when a contact of a ball penetrates deeper than a fraction of its radius
    (`bounds_m`: per party, the bound; inf for parties without a radius) beyond the depth
    its two parties had at the start (a model may start with bodies overlapping: MuJoCo
    runs it, and so does the recorder, until the overlap deepens by the bound)."""

    bounds_m: np.ndarray
    timestep: float
    start: dict[int, float] | None = None  # deepest at step 0, per pair of parties (its key)

    def update(self, chunk: Chunk) -> Verdict | None:
        p1, p2 = chunk.sides
        depth, step = chunk.contacts.penetration, chunk.contacts.step
        pairs = np.minimum(p1, p2) * len(self.bounds_m) + np.maximum(p1, p2)  # a key per pair
        if self.start is None:
            self.start = {}
            for i in np.flatnonzero((step == 0) & (chunk.step0 == 0)):
                self.start[pairs[i]] = max(self.start.get(pairs[i], 0.0), float(depth[i]))
        bound = np.minimum(self.bounds_m[p1], self.bounds_m[p2])
        over = depth > bound
        bound[over] += [self.start.get(pair, 0.0) for pair in pairs[over]]
        over &= depth > bound
        if not over.any():
            return None
        bad = int(step[over].min())
        deepest = float(depth[over & (step == bad)].max())
        limit = float(bound[over & (step == bad)].min())
        t = (chunk.step0 + bad) * self.timestep
        reason = f"penetration {deepest:.4g} m > {limit:.4g} m at t = {t:.6g} s"
        return Verdict(chunk.step0 + bad, "unstable", reason)


class StopMonitor:
    """Evaluates a run's stop rules chunk by chunk; the earliest firing rule wins."""

    def __init__(self, inst: InstrumentedModel, stop: Stop | None, *, timestep: float) -> None:
        stop = Stop.model_construct() if stop is None else stop  # none: the default bounds
        model, nbody = inst.model, len(inst.bodies)
        g = gravity(model)
        mass = float(sum(b.mass for b in inst.bodies))
        residual = _Residual(
            kinetic_adr=inst.energy_adr + 1,
            pos_adr=[b.adr for b in inst.bodies],
            weights=np.array([-b.mass * g for b in inst.bodies]).reshape(-1, 3),
            fraction=stop.max_energy_gain,
            timestep=timestep,
            in_play=max(0.1 * mass * math.hypot(*g), 1e-6),  # 0.1 m of weight; no overflow
        )
        self.rules: list[Callable[[Chunk], Verdict | None]] = [_finite, residual.update]
        bounds = np.full(len(inst.party_names), np.inf)
        bounds[:nbody] = [
            stop.max_penetration * b.radius if b.radius else np.inf for b in inst.bodies
        ]
        if np.isfinite(bounds).any():
            self.rules.append(_Penetration(bounds, timestep).update)
        ground = [g for g in range(model.ngeom) if inst.party[g] >= nbody]  # static geoms
        if stop.bounces is not None:
            own = [np.flatnonzero(inst.party[: model.ngeom] == i).tolist() for i in range(nbody)]
            free = [
                i
                for i, b in enumerate(inst.bodies)
                if b.motion == "free"
                and any(can_collide(model, a, s) for a in own[i] for s in ground)
            ]
            bounces = _Bounces(
                n=stop.bounces,
                bodies=free,
                vel_adr=[inst.bodies[i].adr + 7 for i in free],
                surfaces={nbody + g for g in ground},  # their parties
                up=up_vector(model),
                v_min=min_impact_speed(float(np.linalg.norm(g)), timestep),
            )
            self.rules.append(bounces.update)
        if stop.at_rest:
            steps = max(1, round(stop.rest_time / timestep))
            at_rest = _AtRest(stop.rest_speed, steps, vel_cols=[b.adr + 7 for b in inst.bodies])
            self.rules.append(at_rest.update)
        if stop.separation is not None and inst.gaps:
            gap_cols = [list(c.adrs) for c in inst.gaps]
            self.rules.append(_Separated(stop.separation, gap_cols, nbody).update)

    def update(
        self,
        rows: np.ndarray,
        step0: int,
        contacts: StepContacts,
        episodes: Episodes,
        released: list[Episode],
        work: np.ndarray,
    ) -> Verdict | None:
        """Feed every step from step0 (rows, contacts, work) and the episodes released;
        return the earliest verdict, if any rule fired."""
        inside = contacts.take(contacts.step < rows.shape[0])
        chunk = Chunk(rows, step0, inside, episodes.sides(inside), released, work)
        verdicts = [v for rule in self.rules if (v := rule(chunk)) is not None]
        return min(verdicts, key=lambda v: v.last_step) if verdicts else None
