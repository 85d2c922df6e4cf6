"""Impact and release events of a run: from the analysis tables when given, else from the log
(a release's e then from the recorder's contact work: the analysis' e_energy).

A contact interval is a run of consecutive logged steps on which a pair of bodies touches.
Its impact is the first step in contact, its release the first step after it without contact
(none when the log ends in contact). The plane is the pair partner ``world``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from impactlab.errors import LogError
from impactlab.logs.load import RunLog

ANALYSIS_TABLES = ("bounces", "collisions")
WORLD = "world"


@dataclass(frozen=True)
class Pair:
    """Two bodies that may touch: `first` is ``world`` for the plane."""

    first: str
    second: str

    @property
    def name(self) -> str:
        """A readable label, also used as an entity path part: ``plane-ball``, ``ball1-ball2``."""
        return f"{'plane' if self.first == WORLD else self.first}-{self.second}"


@dataclass(frozen=True)
class Event:
    """One impact or release at a logged step.

    Attributes:
        step: index of the logged step (row of the body frames).
        t_ns: its simulation time, ns.
        kind: ``impact`` or ``release``.
        pair: the bodies, when known.
        text: what the event log shows: one short line.
        details: every number behind it (the analysis row's, the log's velocities), shown
            one click away (the event's `details` in the viewer's selection panel).
    """

    step: int
    t_ns: int
    kind: str
    pair: Pair | None
    text: str
    details: str = ""


@dataclass(frozen=True)
class Interval:
    """Contact of one pair over logged steps `start`..`end` (inclusive).

    `v_in_mps` / `v_out_mps`: relative normal velocity on the step before and after
    (negative: approaching); `release` is None when the log ends in contact.
    """

    pair: Pair
    start: int
    end: int
    release: int | None
    v_in_mps: float
    v_out_mps: float | None


def pairs(run: RunLog) -> list[Pair]:
    """Plane-body pairs (when the run has a plane), then body-body pairs in log order."""
    names = list(run.bodies)
    out = [Pair(WORLD, b) for b in names] if run.plane_z is not None else []
    return out + [Pair(a, b) for i, a in enumerate(names) for b in names[i + 1 :]]


def normal_kinematics(run: RunLog, pair: Pair) -> tuple[np.ndarray, np.ndarray]:
    """Surface gap (m) and relative normal velocity (m/s, negative: approaching), (nstep,) each.

    For the plane: height of the lowest point above the plane and vz. For two spheres: distance
    of the centres minus both radii, and (v2 - v1) along the line from the first to the second.
    """
    radius = {name: b.radius or 0.0 for name, b in run.body_info.items()}  # 0: unknown
    b = run.bodies[pair.second].select("x", "y", "z", "vx", "vy", "vz").to_numpy()
    r2 = radius.get(pair.second, 0.0)
    if pair.first == WORLD:
        return b[:, 2] - r2 - float(run.plane_z or 0.0), b[:, 5]
    a = run.bodies[pair.first].select("x", "y", "z", "vx", "vy", "vz").to_numpy()
    d = b[:, :3] - a[:, :3]
    dist = np.linalg.norm(d, axis=1)
    n = d / np.where(dist > 0, dist, 1.0)[:, None]
    gap = dist - r2 - radius.get(pair.first, 0.0)
    return gap, np.einsum("ij,ij->i", b[:, 3:] - a[:, 3:], n)


def contact_steps(run: RunLog, t_ns: np.ndarray) -> dict[Pair, np.ndarray]:
    """Per pair, the sorted unique indices of the logged steps with contact."""
    known = {(p.first, p.second): p for p in pairs(run)}
    out: dict[Pair, np.ndarray] = {}
    if run.contacts.is_empty():
        return out
    grouped = run.contacts.group_by("body1", "body2").agg(pl.col("t_ns").unique().sort())
    for body1, body2, times in grouped.iter_rows():
        pair = known.get((body1, body2)) or known.get((body2, body1))
        if pair is None:
            continue
        steps = np.searchsorted(t_ns, np.asarray(times, dtype=np.int64))
        steps = steps[(steps < t_ns.size)]
        out[pair] = np.union1d(out.get(pair, np.empty(0, np.int64)), steps)
    return dict(sorted(out.items(), key=lambda kv: kv[0].name))


def contact_intervals(run: RunLog, t_ns: np.ndarray) -> list[Interval]:
    """Every contact interval of every pair, sorted by impact step."""
    out = []
    for pair, steps in contact_steps(run, t_ns).items():
        _, vn = normal_kinematics(run, pair)
        breaks = np.flatnonzero(np.diff(steps) > 1)
        starts = np.concatenate([steps[:1], steps[breaks + 1]])
        ends = np.concatenate([steps[breaks], steps[-1:]])
        for s, e in zip(starts.tolist(), ends.tolist(), strict=True):
            release = e + 1 if e + 1 < t_ns.size else None
            v_out = float(vn[release]) if release is not None else None
            out.append(Interval(pair, s, e, release, float(vn[max(s - 1, 0)]), v_out))
    return sorted(out, key=lambda i: (i.start, i.pair.name))


def log_events(run: RunLog, t_ns: np.ndarray) -> list[Event]:
    """Impact and release events derived from the log's contacts, with the centres' v_in and
    v_out; a release's e is the energetic coefficient from the work the recorder summed over
    the contact's every step (the log's `/contact_work`, the analysis' e_energy), never a
    ratio of the centres' velocities (wrong for a turning body; logs without the work: none)."""
    events = []
    for iv in contact_intervals(run, t_ns):
        who = iv.pair.name
        text = f"impact {who}: v_in = {iv.v_in_mps:.3g} m/s"
        events.append(Event(iv.start, int(t_ns[iv.start]), "impact", iv.pair, text, _v(iv)))
        if iv.release is not None:
            work = _work(run, iv, t_ns)
            details = _v(iv, out=True) + (work[1] if work else "")
            text = f"release {who}: " + (
                f"e = {work[0]:.3g} (energy)" if work else f"v_out = {iv.v_out_mps:.3g} m/s"
            )
            events.append(
                Event(iv.release, int(t_ns[iv.release]), "release", iv.pair, text, details)
            )
    return sorted(events, key=lambda e: e.step)


def _work(run: RunLog, iv: Interval, t_ns: np.ndarray) -> tuple[float, str] | None:
    """The energetic e of an interval and its numbers, from the recorded contacts of its pair
    that start after the logged step before it and no later than its last one."""
    work = run.contact_work
    if work.is_empty():
        return None
    a, b = iv.pair.first, iv.pair.second
    lo = int(t_ns[iv.start - 1]) if iv.start > 0 else -1
    mine = work.filter(
        (
            ((pl.col("body1") == a) & (pl.col("body2") == b))
            | ((pl.col("body1") == b) & (pl.col("body2") == a))
        )
        & (pl.col("start_ns") > lo)
        & (pl.col("start_ns") <= int(t_ns[iv.end]))
    )
    w_c, w_r = mine.select(
        pl.col("work_compression_J").sum(), pl.col("work_restitution_J").sum()
    ).row(0)
    if mine.is_empty() or mine["open"].any() or not w_c < 0:
        return None
    e = float(np.sqrt(w_r / -w_c))
    return e, f", e_energy = {e:.4g} (work {w_c:.4g} J in, {w_r:.4g} J out)"


def _v(iv: Interval, *, out: bool = False) -> str:
    text = f"v_in = {iv.v_in_mps:.4g} m/s"
    if out and iv.v_out_mps is not None:
        text += f", v_out = {iv.v_out_mps:.4g} m/s"
    return text


def load_analysis(folder: Path) -> dict[str, pl.DataFrame]:
    """The analysis tables present in `folder` (`bounces.parquet`, `collisions.parquet`).

    Raises:
        LogError: the folder does not exist, or a table is unreadable or lacks
            `run_id` / `impact_t_s`.
    """
    if not folder.is_dir():
        raise LogError(str(folder), "analysis folder not found")
    tables = {}
    for name in ANALYSIS_TABLES:
        path = folder / f"{name}.parquet"
        if not path.exists():
            continue
        try:
            frame = pl.read_parquet(path)
        except Exception as exc:  # polars raises several error types for damaged files
            raise LogError(str(path), f"cannot read the table ({exc})") from None
        missing = [c for c in ("run_id", "impact_t_s") if c not in frame.columns]
        if missing:
            raise LogError(str(path), f"missing column(s) {', '.join(missing)}")
        tables[name] = frame
    return tables


def analysis_events(
    run: RunLog, t_ns: np.ndarray, tables: Mapping[str, pl.DataFrame]
) -> list[Event] | None:
    """Events from the analysis rows of this run (None when no table has a row for it).

    Each row gives an impact at `impact_t_s` and, when not null, a release at `release_t_s`,
    snapped to the nearest logged step. The texts carry the row's numbers, and the log's
    v_in / v_out when a contact interval of the log starts within two steps of the impact.
    """
    rows = [
        (name, row)
        for name, frame in tables.items()
        for row in frame.filter(pl.col("run_id") == run.run_id).iter_rows(named=True)
    ]
    if not rows:
        return None
    intervals = contact_intervals(run, t_ns)
    only = pairs(run)[0] if len(pairs(run)) == 1 else None
    events = []
    for table, row in rows:
        if row.get("impact_t_s") is None:  # a row saying why nothing happened (no impact)
            continue
        impact = _nearest_step(t_ns, row["impact_t_s"])
        iv = min(intervals, key=lambda i: abs(i.start - impact), default=None)
        iv = iv if iv is not None and abs(iv.start - impact) <= 2 else None
        pair = iv.pair if iv is not None else only
        kind = table.removesuffix("s")
        number = row.get(kind)
        who = f"{kind}{f' {number}' if isinstance(number, int) else ''}"
        who = f"{who} {pair.name if pair else ''}".rstrip()
        numbers = _numbers(row)
        headline = _headline(row)
        extra = f"; log: {_v(iv)}" if iv else ""
        text = f"impact {who}" + (f": {headline}" if headline else "")
        events.append(Event(impact, int(t_ns[impact]), "impact", pair, text, numbers + extra))
        if row.get("release_t_s") is not None:
            release = _nearest_step(t_ns, row["release_t_s"])
            extra = f"; log: {_v(iv, out=True)}" if iv else ""
            text = f"release {who}" + (f": {headline}" if headline else "")
            events.append(
                Event(release, int(t_ns[release]), "release", pair, text, numbers + extra)
            )
    return sorted(events, key=lambda e: e.step)


HEADLINE_COLUMNS = ("e_velocity", "e_measured", "e")
"""The analysis column an event's short text shows (the first present), its restitution."""


def _headline(row: Mapping[str, object]) -> str:
    for key in HEADLINE_COLUMNS:
        value = row.get(key)
        if isinstance(value, int | float) and not isinstance(value, bool):
            return f"{key} = {value:.3g}"
    return ""


def _nearest_step(t_ns: np.ndarray, t_s: float) -> int:
    target = round(float(t_s) * 1e9)
    i = int(np.searchsorted(t_ns, target))
    candidates = [j for j in (i - 1, i) if 0 <= j < t_ns.size]
    return min(candidates, key=lambda j: abs(int(t_ns[j]) - target))


def _numbers(row: Mapping[str, object]) -> str:
    """`name = value` for the row's numeric and text columns (not run_id, not the times)."""
    parts = []
    for key, value in row.items():
        if key in ("run_id", "impact_t_s", "release_t_s") or value is None:
            continue
        if isinstance(value, bool | str):
            parts.append(f"{key} = {value}")
        elif isinstance(value, int | float):
            parts.append(f"{key} = {value:.4g}")
    return ", ".join(parts)


def events_for(
    run: RunLog, t_ns: np.ndarray, tables: Mapping[str, pl.DataFrame] | None
) -> list[Event]:
    """The analysis events of the run when `tables` has rows for it, else the log's."""
    found = analysis_events(run, t_ns, tables) if tables else None
    return found if found is not None else log_events(run, t_ns)
