"""Stop rules evaluated on chunks of sensordata, vectorised, with state carried between chunks.

Each rule sees every simulated step (not only the logged ones) as rows of sensordata, and
returns the global step index of the last row to keep when it fires.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from impactlab.record.geometry import gravity, up_vector
from impactlab.record.model import InstrumentedModel
from impactlab.record.spec import Stop

if TYPE_CHECKING:
    import mujoco


@dataclass
class Verdict:
    """Why a run stopped: the last step kept, the outcome and a sentence for people."""

    last_step: int
    outcome: str  # "completed" or "unstable"
    reason: str


class _Rule:
    def update(self, rows: np.ndarray, step0: int) -> Verdict | None:
        raise NotImplementedError


def _first(mask: np.ndarray) -> int | None:
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None


@dataclass
class _Finite(_Rule):
    def update(self, rows: np.ndarray, step0: int) -> Verdict | None:
        bad = _first(~np.isfinite(rows).all(axis=1))
        if bad is None:
            return None
        return Verdict(
            step0 + bad - 1, "unstable", f"state became non-finite at step {step0 + bad}"
        )


@dataclass
class _Bounces(_Rule):
    """Stop at the apex after the N-th bounce of every body that touches the ground.

    A body touches the ground when any of its contact sensors with a ground surface finds a
    contact (`contact_cols`: per body, those sensors' columns); its apex is the first step
    after the N-th release whose velocity along -gravity (`vel_cols`: the body's linear
    velocity, 3 columns) is not positive.
    """

    n: int
    contact_cols: list[list[int]]
    vel_cols: list[int]
    up: np.ndarray
    in_contact: list[bool] = field(default_factory=list)
    count: list[int] = field(default_factory=list)
    done_step: list[int | None] = field(default_factory=list)

    def __post_init__(self) -> None:
        k = len(self.contact_cols)
        self.in_contact, self.count, self.done_step = [False] * k, [0] * k, [None] * k

    def update(self, rows: np.ndarray, step0: int) -> Verdict | None:
        for b, (ccols, vcol) in enumerate(zip(self.contact_cols, self.vel_cols, strict=True)):
            if self.done_step[b] is not None:
                continue
            touching = np.asarray((rows[:, ccols] > 0).any(axis=1))
            before = np.concatenate([[self.in_contact[b]], touching[:-1]])
            released = before & ~touching
            total = self.count[b] + np.cumsum(released)
            self.in_contact[b] = bool(touching[-1])
            reached = total >= self.n
            v_up = rows[:, vcol : vcol + 3] @ self.up
            apex = _first(reached & ~touching & (v_up <= 0.0))
            self.count[b] = int(total[-1])
            if apex is not None:
                self.done_step[b] = step0 + apex
        if self.done_step and all(s is not None for s in self.done_step):
            last = max(s for s in self.done_step if s is not None)
            return Verdict(last, "completed", f"apex after bounce {self.n}")
        return None


@dataclass
class _AtRest(_Rule):
    """Stop once every body is slower than `speed` for `steps` consecutive steps."""

    speed: float
    steps: int
    vel_cols: list[int]
    run: int = 0

    def update(self, rows: np.ndarray, step0: int) -> Verdict | None:
        speeds = np.stack([np.linalg.norm(rows[:, c : c + 3], axis=1) for c in self.vel_cols])
        slow = (speeds < self.speed).all(axis=0)
        # length of the run of slow steps ending at each row, continuing the previous chunk's
        breaks = np.flatnonzero(~slow)
        idx = np.arange(slow.size)
        last_break = np.full(slow.size, -1 - self.run)
        if breaks.size:
            marks = np.full(slow.size, -1 - self.run)
            marks[breaks] = breaks
            last_break = np.maximum.accumulate(marks)
        length = idx - last_break
        hit = _first(length >= self.steps)
        self.run = int(length[-1])
        if hit is None:
            return None
        return Verdict(step0 + hit, "completed", "bodies at rest")


@dataclass
class _Separated(_Rule):
    """Stop once two bodies have touched and their surfaces are `gap_m` apart again.

    `gap_cols`: per pair of bodies, the columns of MuJoCo's distance sensors between their
    geoms (the gap is the smallest).
    """

    gap_m: float
    contact_cols: list[int]
    gap_cols: list[list[int]]
    touched: bool = False

    def update(self, rows: np.ndarray, step0: int) -> Verdict | None:
        touching = np.zeros(rows.shape[0], dtype=bool)
        for c in self.contact_cols:
            touching |= rows[:, c] > 0
        seen = self.touched | (np.cumsum(touching) > 0)
        self.touched = bool(seen[-1])
        gaps = np.stack([rows[:, cols].min(axis=1) for cols in self.gap_cols]).min(axis=0)
        hit = _first(seen & ~touching & (gaps >= self.gap_m))
        if hit is None:
            return None
        return Verdict(step0 + hit, "completed", f"bodies separated by {self.gap_m:g} m")


@dataclass
class _EnergyGain(_Rule):
    """Unstable when MuJoCo's own mechanical energy (kinetic plus potential: gravity and
    springs, every body and joint) grows beyond a bound while the model has no source.

    `adr`: the column of MuJoCo's potential energy sensor; its kinetic one follows.
    """

    adr: int
    fraction: float
    timestep: float
    floor_J: float
    energy_start: float | None = None
    scale: float = 0.0

    def update(self, rows: np.ndarray, step0: int) -> Verdict | None:
        potential, kinetic = rows[:, self.adr], rows[:, self.adr + 1]
        energy = kinetic + potential
        if self.energy_start is None:
            self.energy_start = float(energy[0])
            self.scale = max(float(kinetic[0] + abs(potential[0])), self.floor_J, 1e-6)
        gain = energy - self.energy_start
        bad = _first(gain > self.fraction * self.scale)
        if bad is None:
            return None
        t = (step0 + bad) * self.timestep
        reason = (
            f"MuJoCo's energy grew by {gain[bad]:.4g} J (bound {self.fraction:g} x "
            f"{self.scale:.4g} J) at t = {t:.6g} s with no source"
        )
        return Verdict(step0 + bad, "unstable", reason)


def energy_sources(model: mujoco.MjModel) -> list[str]:
    """What can feed a model's energy with no control input: actuators with a bias force
    (position or velocity servos), gravity compensation. Empty: the energy cannot grow."""
    sources = []
    if model.nu and np.any(model.actuator_biasprm[:, :3] != 0):
        sources.append("actuators with a bias force")
    if np.any(model.body_gravcomp > 0):
        sources.append("gravity compensation")
    return sources


@dataclass
class _Penetration(_Rule):
    """Unstable when a contact penetrates deeper than a bound (m) for its pair."""

    dist_cols: list[int]
    bounds_m: list[float]
    timestep: float

    def update(self, rows: np.ndarray, step0: int) -> Verdict | None:
        for col, bound in zip(self.dist_cols, self.bounds_m, strict=True):
            found = rows[:, col - 4] > 0
            bad = _first(found & (-rows[:, col] > bound))
            if bad is not None:
                t = (step0 + bad) * self.timestep
                reason = f"penetration {-rows[bad, col]:.4g} m > {bound:.4g} m at t = {t:.6g} s"
                return Verdict(step0 + bad, "unstable", reason)
        return None


class StopMonitor:
    """Evaluates a run's stop rules chunk by chunk; the earliest firing rule wins."""

    def __init__(self, inst: InstrumentedModel, stop: Stop | None, *, timestep: float) -> None:
        self.rules: list[_Rule] = [_Finite()]
        self.bodybody_cols: list[int] = []
        model = inst.model
        gain = stop.max_energy_gain if stop else Stop.model_fields["max_energy_gain"].default
        if not energy_sources(model):
            mass = float(sum(model.body_mass[b.body_id] for b in inst.bodies))
            self.rules.append(
                _EnergyGain(
                    adr=inst.energy_adr,
                    fraction=gain,
                    timestep=timestep,
                    floor_J=0.1 * mass * math.hypot(*gravity(model)),  # no overflow
                )
            )
        radius = {b.name: b.radius for b in inst.bodies}
        fraction = stop.max_penetration if stop else Stop.model_fields["max_penetration"].default
        limited = [
            (c.adr + 4, fraction * min(r for r in (radius.get(c.body1), radius[c.body2]) if r))
            for c in inst.contacts
            if c.num == 1 and radius.get(c.body2)
        ]
        if limited:
            self.rules.append(
                _Penetration([c for c, _ in limited], [b for _, b in limited], timestep)
            )
        if stop is None:
            return
        by_name = {b.name: b for b in inst.bodies}
        ground = {s.name for s in inst.surfaces}
        bodybody = [c for c in inst.contacts if c.body1 in by_name and c.body2 in by_name]
        self.bodybody_cols = [c.adr for c in bodybody]
        if stop.bounces is not None:
            landing = {
                b.name: [c.adr for c in inst.contacts if c.geom1 in ground and c.body2 == b.name]
                for b in inst.bodies
                if b.motion == "free"  # an apex is a free body's
            }
            landing = {name: cols for name, cols in landing.items() if cols}
            self.rules.append(
                _Bounces(
                    n=stop.bounces,
                    contact_cols=list(landing.values()),
                    vel_cols=[by_name[name].adr + 7 for name in landing],
                    up=up_vector(model),
                )
            )
        if stop.at_rest:
            self.rules.append(
                _AtRest(
                    speed=stop.rest_speed,
                    steps=max(1, round(stop.rest_time / timestep)),
                    vel_cols=[b.adr + 7 for b in inst.bodies],
                )
            )
        if stop.separation is not None and inst.gaps:
            self.rules.append(
                _Separated(
                    gap_m=stop.separation,
                    contact_cols=self.bodybody_cols,
                    gap_cols=[list(g.adrs) for g in inst.gaps],
                )
            )

    def update(self, rows: np.ndarray, step0: int) -> Verdict | None:
        """Feed rows for steps step0.. ; return the earliest verdict, if any rule fired."""
        verdicts = [v for rule in self.rules if (v := rule.update(rows, step0)) is not None]
        return min(verdicts, key=lambda v: v.last_step) if verdicts else None
