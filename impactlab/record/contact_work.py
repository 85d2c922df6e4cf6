"""The work of each contact's normal force, accumulated over every simulated step.

The energetic coefficient of restitution (Stronge) of a contact is e*^2 = W_r / -W_c: the
work the normal force does on the contact points' relative normal motion while they separate
(W_r >= 0) against the work while they approach (W_c <= 0). It is at most 1 for a contact
that dissipates, whatever the bodies' rotation, friction or joints; the velocity ratio at the
contact point is not (a turning body's contact point can leave faster than it arrived).
It needs every step of the contact, so the recorder accumulates it here, from the rows the
stop rules see, and logs one `ContactWork` per contact (`/contact_work/<g1>/<g2>`).

At each step, per contact point k of a pair: f_k, the normal force (from the contact sensor,
>= 0), and v_k = n_k . (v_2(p_k) - v_1(p_k)), with n_k the normal from geom1 to geom2 and
v_b(p) = v_b + w_b x (p - c_b) the velocity of body b's material point at p (c_b its centre
of mass, 0 for a static body). The step's power P = sum_k f_k v_k, times the timestep, goes
to W_c when negative, to W_r when positive.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from impactlab.record.model import CONTACT_SLOT_SIZE, InstrumentedModel

WORK_FIELDS = ("start_step", "end_step", "work_c", "work_r", "v_start", "v_end", "open")
"""Columns of an episode array: steps (global indices), J, J, m/s, m/s, 0/1."""


@dataclass
class _Pair:
    adr: int
    num: int
    body1: int | None  # sensordata column of body 1's state, None when static
    body2: int | None
    open_start: int | None = None
    work_c: float = 0.0
    work_r: float = 0.0
    v_start: float = 0.0
    v_last: float = 0.0
    last_step: int = 0
    episodes: list[tuple[float, ...]] = field(default_factory=list)


class ContactWork:
    """Accumulates each pair's contacts of one run, chunk by chunk (see the module docstring)."""

    def __init__(self, inst: InstrumentedModel, timestep: float) -> None:
        state = {b.name: b.adr for b in inst.bodies}
        self.dt = timestep
        self.pairs = [
            _Pair(c.adr, c.num, state.get(c.body1), state.get(c.body2)) for c in inst.contacts
        ]

    def update(self, rows: np.ndarray, step0: int) -> None:
        """Feed the rows of steps step0 .. step0 + len(rows) - 1 (every simulated step)."""
        if not rows.shape[0]:
            return
        for pair in self.pairs:
            found = rows[:, pair.adr]
            if pair.open_start is None and not (found > 0).any():
                continue
            power, v_mean = self._power(pair, rows)
            touching = found > 0
            self._episodes(pair, touching, power, v_mean, step0)

    def _power(self, pair: _Pair, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The normal power (W) and mean normal velocity (m/s) of the pair at each row."""
        n = rows.shape[0]
        count = np.minimum(rows[:, pair.adr], pair.num)
        power, v_sum = np.zeros(n), np.zeros(n)
        for k in range(pair.num):
            at = pair.adr + k * CONTACT_SLOT_SIZE
            active = count > k
            force = rows[:, at + 1]
            p, normal = rows[:, at + 5 : at + 8], rows[:, at + 8 : at + 11]
            v = _point_velocity(rows, pair.body2, p) - _point_velocity(rows, pair.body1, p)
            v_n = np.einsum("ij,ij->i", normal, v)
            power += np.where(active, force * v_n, 0.0)
            v_sum += np.where(active, v_n, 0.0)
        v_mean = np.divide(v_sum, count, out=np.zeros(n), where=count > 0)
        return power, v_mean

    def _episodes(
        self,
        pair: _Pair,
        touching: np.ndarray,
        power: np.ndarray,
        v_mean: np.ndarray,
        step0: int,
    ) -> None:
        """Split the rows into contacts, carrying one still going on across chunks."""
        if pair.open_start is not None and not touching[0]:
            self._close(pair)  # it ended with the previous chunk
        edges = np.flatnonzero(np.diff(np.concatenate([[0], touching.astype(np.int8), [0]])))
        for lo, hi in zip(edges[0::2], edges[1::2], strict=True):  # [lo, hi): in contact
            if pair.open_start is None:
                pair.open_start, pair.work_c, pair.work_r = step0 + int(lo), 0.0, 0.0
                pair.v_start = float(v_mean[lo])
            seg = power[lo:hi] * self.dt
            pair.work_c += float(seg[seg < 0].sum())
            pair.work_r += float(seg[seg > 0].sum())
            pair.v_last, pair.last_step = float(v_mean[hi - 1]), step0 + int(hi) - 1
            if hi < touching.size:
                self._close(pair)

    def _close(self, pair: _Pair, *, still_open: bool = False) -> None:
        assert pair.open_start is not None
        pair.episodes.append(
            (
                pair.open_start,
                pair.last_step,
                pair.work_c,
                pair.work_r,
                pair.v_start,
                pair.v_last,
                float(still_open),
            )
        )
        pair.open_start = None

    def finish(self) -> list[np.ndarray]:
        """Each pair's contacts, (k, 7) in `WORK_FIELDS` order; a contact still going on at
        the end is closed and marked open."""
        out = []
        for pair in self.pairs:
            if pair.open_start is not None:
                self._close(pair, still_open=True)
            out.append(np.array(pair.episodes, dtype=float).reshape(-1, len(WORK_FIELDS)))
        return out


def _point_velocity(rows: np.ndarray, adr: int | None, p: np.ndarray) -> np.ndarray:
    """World velocity of a body's material point at p (n, 3); zero for a static body."""
    if adr is None:
        return np.zeros_like(p)
    com, v, w = rows[:, adr : adr + 3], rows[:, adr + 7 : adr + 10], rows[:, adr + 10 : adr + 13]
    return v + np.cross(w, p - com)
