"""Contact episodes between parties (rigid bodies, surfaces, flexes), found at every step."""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass, field

import numpy as np

from impactlab.physics import MIN_FLIGHT_STEPS
from impactlab.record.contacts import StepContacts
from impactlab.record.model import BODY_STATE_SIZE, InstrumentedModel


@dataclass
class Episode:
    """One contact of a pair of parties, from its first step to its last (global steps).

    `side1` < `side2` are party ids (`InstrumentedModel.party_names`); normals point from
    side 1 to side 2. Velocities are the relative normal velocity of the contact points
    (< 0: approaching), MuJoCo's J v: `v_in` before any contact force acted (the velocity the
    surfaces met with: at the start of the first step in contact, for RK4 at the start of
    the step before, whose later stages met the surface), `v_out` after the last step in
    contact (the one they parted with),
    each the mean over the pair's contact points then. Works (J) are the normal force's
    while the points approach (`work_c` <= 0) and separate (`work_r` >= 0) and the friction
    force's; `state_in`/`state_out` the two sides' states (13 values each, NaN for a side
    that is not a rigid body) at the first step in contact and the first step after.
    """

    side1: int
    side2: int
    geom1: int
    geom2: int
    onset: int
    last: int
    v_in: float
    v_out: float = float("nan")
    point_in: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    normal_in: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    point_out: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    normal_out: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    state_in: np.ndarray = field(default_factory=lambda: np.full((2, BODY_STATE_SIZE), np.nan))
    state_out: np.ndarray = field(default_factory=lambda: np.full((2, BODY_STATE_SIZE), np.nan))
    work_c: float = 0.0
    work_r: float = 0.0
    work_f: float = 0.0
    peak_force: float = 0.0
    impulse: float = 0.0
    max_penetration: float = 0.0
    steps: int = 0
    open: bool = False

    @property
    def confirmed(self) -> int:
        """The step at which the release is certain: `MIN_FLIGHT_STEPS` steps apart."""
        return self.last + MIN_FLIGHT_STEPS


@dataclass
class _PairSteps:
    """One pair's aggregates per step in contact within a chunk (local steps)."""

    steps: np.ndarray
    force: np.ndarray
    power_n: np.ndarray
    power_f: np.ndarray
    penetration: np.ndarray
    v_start: np.ndarray
    v_end: np.ndarray
    v_arrive: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    geoms: np.ndarray  # (k, 2) the first contact's geoms at each step


def _copy(episode: Episode) -> Episode:
    """A copy of `episode` that shares no array with it."""
    return dataclasses.replace(
        episode,
        point_in=episode.point_in.copy(),
        normal_in=episode.normal_in.copy(),
        point_out=episode.point_out.copy(),
        normal_out=episode.normal_out.copy(),
        state_in=episode.state_in.copy(),
        state_out=episode.state_out.copy(),
    )


class Episodes:
    """A run's contact episodes, chunk by chunk; contacts fewer than `MIN_FLIGHT_STEPS` steps
    apart are one episode (a resting, sliding or rolling contact flickers in MuJoCo)."""

    def __init__(self, inst: InstrumentedModel, timestep: float) -> None:
        self.dt = timestep
        self.party = inst.party
        self.ngeom = int(inst.model.ngeom)
        self.nparty = len(inst.party_names)
        self.state_adr = [b.adr for b in inst.bodies]
        self.open: dict[int, Episode] = {}
        self.closed: list[Episode] = []

    def snapshot(self) -> tuple[dict[int, Episode], int]:
        """What `restore` needs to undo the next updates."""
        return {key: _copy(e) for key, e in self.open.items()}, len(self.closed)

    def restore(self, saved: tuple[dict[int, Episode], int]) -> None:
        self.open = {key: _copy(e) for key, e in saved[0].items()}
        del self.closed[saved[1] :]

    def sides(self, contacts: StepContacts) -> tuple[np.ndarray, np.ndarray]:
        """Each contact's two parties (not ordered)."""
        p1 = np.where(contacts.geom1 >= 0, contacts.geom1, self.ngeom + contacts.flex1)
        p2 = np.where(contacts.geom2 >= 0, contacts.geom2, self.ngeom + contacts.flex2)
        return self.party[p1], self.party[p2]

    def update(self, contacts: StepContacts, rows: np.ndarray, step0: int) -> list[Episode]:
        """Take a chunk's contacts (local steps) and sensordata rows (every step from
        `step0`); returns the episodes whose release became certain in this chunk."""
        n = rows.shape[0]
        before = len(self.closed)
        for ep in self.open.values():  # a release after the previous chunk's last step
            if np.isnan(ep.state_out).all() and ep.last == step0 - 1:
                self._state(ep.state_out, ep, rows[0])
        for key, pair in self._pairs(contacts).items():
            self._pair(key, pair, rows, step0)
        end = step0 + n - 1
        for key in [k for k, ep in self.open.items() if ep.confirmed <= end]:
            self.closed.append(self.open.pop(key))
        return self.closed[before:]

    def finish(self, last_step: int) -> list[Episode]:
        """Every episode of the run, in order of release; one in contact at the run's last
        step is marked open."""
        for ep in self.open.values():
            ep.open = ep.last >= last_step
            self.closed.append(ep)
        self.open = {}
        return sorted(self.closed, key=lambda ep: (ep.last, ep.side1, ep.side2))

    def _pairs(self, contacts: StepContacts) -> dict[int, _PairSteps]:
        """The chunk's contacts aggregated per pair of parties and step."""
        if not len(contacts):
            return {}
        p1, p2 = self.sides(contacts)
        lo, hi = np.minimum(p1, p2), np.maximum(p1, p2)
        flip = np.where(p1 > p2, -1.0, 1.0)
        keep = lo != hi  # a flex touching itself is no episode
        key = (lo * self.nparty + hi)[keep]
        step = contacts.step[keep]
        order = np.lexsort((step, key))
        key, step = key[order], step[order]
        pick = np.flatnonzero(keep)[order]
        starts = np.flatnonzero(np.r_[True, (np.diff(key) != 0) | (np.diff(step) != 0)])
        count = np.diff(np.r_[starts, key.size])

        def total(values: np.ndarray) -> np.ndarray:
            return np.add.reduceat(values[pick], starts, axis=0)

        normal = total(contacts.frame[:, :3] * flip[:, None])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True).clip(1e-300)
        group_key = key[starts]
        out: dict[int, _PairSteps] = {}
        bounds = np.flatnonzero(np.r_[True, np.diff(group_key) != 0, True])
        force, pen = total(contacts.force[:, 0]), contacts.penetration[pick]
        p_n, p_f = total(contacts.power_normal), total(contacts.power_friction)
        v_start, v_end = total(contacts.v_start) / count, total(contacts.v_end) / count
        v_arrive = total(contacts.v_arrive) / count
        point = total(contacts.pos) / count[:, None]
        geoms = np.stack([contacts.geom1[pick][starts], contacts.geom2[pick][starts]], axis=1)
        penetration = np.maximum.reduceat(pen, starts)
        for a, b in itertools.pairwise(bounds):
            out[int(group_key[a])] = _PairSteps(
                step[starts[a:b]],
                force[a:b],
                p_n[a:b],
                p_f[a:b],
                penetration[a:b],
                v_start[a:b],
                v_end[a:b],
                v_arrive[a:b],
                point[a:b],
                normal[a:b],
                geoms[a:b],
            )
        return out

    def _pair(self, key: int, pair: _PairSteps, rows: np.ndarray, step0: int) -> None:
        """Extend, close and open the pair's episodes with its steps of this chunk."""
        steps = pair.steps + step0
        breaks = np.flatnonzero(np.diff(steps) > MIN_FLIGHT_STEPS) + 1
        bounds = [0, *breaks.tolist(), steps.size]
        for a, b in itertools.pairwise(bounds):
            ep = self.open.get(key)
            if ep is not None and steps[a] - ep.last > MIN_FLIGHT_STEPS:
                self.closed.append(self.open.pop(key))
                ep = None
            if ep is None:
                ep = self._start(key, pair, a, steps[a], rows[pair.steps[a]])
                self.open[key] = ep
            seg = slice(a, b)
            power = pair.power_n[seg] * self.dt
            ep.work_c += float(power[power < 0].sum())
            ep.work_r += float(power[power > 0].sum())
            ep.work_f += float(pair.power_f[seg].sum() * self.dt)
            ep.peak_force = max(ep.peak_force, float(pair.force[seg].max()))
            ep.impulse += float(pair.force[seg].sum() * self.dt)
            ep.max_penetration = max(ep.max_penetration, float(pair.penetration[seg].max()))
            ep.steps += b - a
            ep.last = int(steps[b - 1])
            ep.v_out = float(pair.v_end[b - 1])
            ep.point_out, ep.normal_out = pair.point[b - 1], pair.normal[b - 1]
            ep.state_out = np.full((2, BODY_STATE_SIZE), np.nan)
            after = pair.steps[b - 1] + 1
            if after < rows.shape[0]:
                self._state(ep.state_out, ep, rows[after])
            if b < steps.size:  # another episode of the pair follows in this chunk
                self.closed.append(self.open.pop(key))

    def _start(self, key: int, pair: _PairSteps, i: int, step: int, row: np.ndarray) -> Episode:
        ep = Episode(
            side1=key // self.nparty,
            side2=key % self.nparty,
            geom1=int(pair.geoms[i, 0]),
            geom2=int(pair.geoms[i, 1]),
            onset=int(step),
            last=int(step),
            v_in=float(pair.v_arrive[i]),
            point_in=pair.point[i],
            normal_in=pair.normal[i],
        )
        self._state(ep.state_in, ep, row)
        return ep

    def _state(self, out: np.ndarray, ep: Episode, row: np.ndarray) -> None:
        for k, side in enumerate((ep.side1, ep.side2)):
            if side < len(self.state_adr):
                adr = self.state_adr[side]
                out[k] = row[adr : adr + BODY_STATE_SIZE]
