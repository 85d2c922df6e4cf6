"""Contact episodes between parties (rigid bodies, surfaces, flexes), found at every step."""

from __future__ import annotations

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
class _Segments:
    """A chunk's contacts as runs of steps of one pair, fewer than `MIN_FLIGHT_STEPS` steps
    apart (local steps), in order of pair then step: per run its aggregates, first and
    last step's values. Lists, for the loop over runs (`Episodes._segment`)."""

    key: list[int]
    first: list[int]
    last: list[int]
    continued: list[bool]  # the pair's next run in this chunk follows
    work_c: list[float]
    work_r: list[float]
    work_f: list[float]
    peak_force: list[float]
    impulse: list[float]
    max_penetration: list[float]
    steps: list[int]
    v_arrive: list[float]  # at the first step
    v_end: list[float]  # at the last step
    point: np.ndarray  # (runs, 2, 3): at the first and the last step
    normal: np.ndarray  # (runs, 2, 3)
    geoms: list[list[int]]  # the first contact's geoms at the first step
    sides: np.ndarray  # (runs, 2): the pair's parties


class Episodes:
    """A run's contact episodes, chunk by chunk; contacts fewer than `MIN_FLIGHT_STEPS` steps
    apart are one episode (a resting, sliding or rolling contact flickers in MuJoCo)."""

    def __init__(self, inst: InstrumentedModel, timestep: float) -> None:
        self.dt = timestep
        self.party = inst.party
        self.ngeom = int(inst.model.ngeom)
        self.nparty = len(inst.party_names)
        # per party, where its 13 state values start in sensordata (-1: not a rigid body)
        self.state_adr = np.full(self.nparty, -1, np.int64)
        self.state_adr[: len(inst.bodies)] = [b.adr for b in inst.bodies]
        self.open: dict[int, Episode] = {}
        self.closed: list[Episode] = []

    def snapshot(self) -> tuple[dict[int, Episode], int]:
        """What `restore` needs to undo the next updates: shallow copies, as an episode's
        arrays are replaced, never written into, once it exists."""
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
        # in contact at the previous chunk's last step: the state after it is this one's first
        ended = [
            ep for ep in self.open.values() if ep.last == step0 - 1 and np.isnan(ep.state_out).all()
        ]
        if ended:
            sides = np.array([[ep.side1, ep.side2] for ep in ended])
            after = self._states(rows, np.zeros(len(ended), np.int64), sides)
            for ep, state in zip(ended, after, strict=True):
                ep.state_out = state.copy()
        runs = self._segments(contacts)
        if runs is not None:
            first, last = np.array(runs.first), np.array(runs.last)
            state_in = self._states(rows, first, runs.sides)
            state_out = self._states(rows, last + 1, runs.sides)
            for i in range(len(runs.key)):
                self._segment(runs, i, step0, state_in[i], state_out[i])
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

    def _segments(self, contacts: StepContacts) -> _Segments | None:
        """The chunk's contacts aggregated per pair of parties and step, then per run of
        steps of a pair (None without contacts)."""
        if not len(contacts):
            return None
        p1, p2 = self.sides(contacts)
        lo, hi = np.minimum(p1, p2), np.maximum(p1, p2)
        flip = np.where(p1 > p2, -1.0, 1.0)
        keep = lo != hi  # a flex touching itself is no episode
        key = (lo * self.nparty + hi)[keep]
        step = contacts.step[keep]
        order = np.lexsort((step, key))
        key, step = key[order], step[order]
        pick = np.flatnonzero(keep)[order]
        if not pick.size:
            return None
        starts = np.flatnonzero(np.r_[True, (np.diff(key) != 0) | (np.diff(step) != 0)])
        count = np.diff(np.r_[starts, key.size])

        def total(values: np.ndarray) -> np.ndarray:
            return np.add.reduceat(values[pick], starts, axis=0)

        # per pair and step
        normal = total(contacts.frame[:, :3] * flip[:, None])
        normal /= np.linalg.norm(normal, axis=1, keepdims=True).clip(1e-300)
        force = total(contacts.force[:, 0])
        power_n = total(contacts.power_normal) * self.dt
        point = total(contacts.pos) / count[:, None]
        penetration = np.maximum.reduceat(contacts.penetration[pick], starts)
        key, step = key[starts], step[starts]
        # per run: a new one at another pair or after a gap of more than MIN_FLIGHT_STEPS
        new_pair = np.r_[True, key[1:] != key[:-1]]
        first = np.flatnonzero(new_pair | np.r_[True, np.diff(step) > MIN_FLIGHT_STEPS])
        last = np.r_[first[1:], key.size] - 1
        geoms = np.stack([contacts.geom1[pick][starts], contacts.geom2[pick][starts]], axis=1)
        return _Segments(
            key=key[first].tolist(),
            first=step[first].tolist(),
            last=step[last].tolist(),
            continued=np.r_[~new_pair[first[1:]], False].tolist(),
            work_c=np.add.reduceat(np.minimum(power_n, 0.0), first).tolist(),
            work_r=np.add.reduceat(np.maximum(power_n, 0.0), first).tolist(),
            work_f=(np.add.reduceat(total(contacts.power_friction), first) * self.dt).tolist(),
            peak_force=np.maximum.reduceat(force, first).tolist(),
            impulse=(np.add.reduceat(force, first) * self.dt).tolist(),
            max_penetration=np.maximum.reduceat(penetration, first).tolist(),
            steps=(last - first + 1).tolist(),
            v_arrive=(total(contacts.v_arrive) / count)[first].tolist(),
            v_end=(total(contacts.v_end) / count)[last].tolist(),
            point=np.stack([point[first], point[last]], axis=1),
            normal=np.stack([normal[first], normal[last]], axis=1),
            geoms=geoms[first].tolist(),
            sides=np.stack(np.divmod(key[first], self.nparty), axis=1),
        )

    def _segment(
        self, runs: _Segments, i: int, step0: int, state_in: np.ndarray, state_out: np.ndarray
    ) -> None:
        """Extend the pair's open episode with run i of this chunk, or close it and open
        another (`state_in`, `state_out`: the sides' states at the run's first step and the
        step after its last)."""
        key = runs.key[i]
        ep = self.open.get(key)
        if ep is not None and step0 + runs.first[i] - ep.last > MIN_FLIGHT_STEPS:
            self.closed.append(self.open.pop(key))
            ep = None
        if ep is None:
            ep = Episode(
                side1=key // self.nparty,
                side2=key % self.nparty,
                geom1=runs.geoms[i][0],
                geom2=runs.geoms[i][1],
                onset=step0 + runs.first[i],
                last=step0 + runs.first[i],
                v_in=runs.v_arrive[i],
                point_in=runs.point[i, 0],
                normal_in=runs.normal[i, 0],
            )
            ep.state_in = state_in.copy()  # a copy: the chunk's arrays are not kept
            self.open[key] = ep
        ep.work_c += runs.work_c[i]
        ep.work_r += runs.work_r[i]
        ep.work_f += runs.work_f[i]
        ep.peak_force = max(ep.peak_force, runs.peak_force[i])
        ep.impulse += runs.impulse[i]
        ep.max_penetration = max(ep.max_penetration, runs.max_penetration[i])
        ep.steps += runs.steps[i]
        ep.last = step0 + runs.last[i]
        ep.v_out = runs.v_end[i]
        ep.point_out, ep.normal_out = runs.point[i, 1], runs.normal[i, 1]
        ep.state_out = state_out.copy()
        if runs.continued[i]:  # another episode of the pair follows in this chunk
            self.closed.append(self.open.pop(key))

    def _states(self, rows: np.ndarray, at: np.ndarray, sides: np.ndarray) -> np.ndarray:
        """Pairs' sides' states (k, 2, 13) in sensordata `rows` at rows `at` (k,), for
        `sides` (k, 2) parties; NaN for a side that is not a rigid body, or for both past
        the rows."""
        out = np.full((len(at), 2, BODY_STATE_SIZE), np.nan)
        adr = self.state_adr[sides]
        ok = (adr >= 0) & (at < rows.shape[0])[:, None]
        row = np.broadcast_to(at[:, None], adr.shape)[ok]
        out[ok] = rows[row[:, None], adr[ok][:, None] + np.arange(BODY_STATE_SIZE)]
        return out


def _copy(ep: Episode) -> Episode:
    """A shallow copy (`copy.copy` costs ten times as much)."""
    new = object.__new__(Episode)
    new.__dict__.update(ep.__dict__)
    return new
