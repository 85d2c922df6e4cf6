"""Impact and release events of a run: the recorder's contact episodes, or the analysis rows."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from impactlab import physics
from impactlab.errors import LogError
from impactlab.logs.load import RunLog

ANALYSIS_TABLES = ("bounces", "collisions")


@dataclass(frozen=True)
class Pair:
    """Two parties that touched (a surface first when one is): `first`, `second`."""

    first: str
    second: str

    @property
    def name(self) -> str:
        """A readable label, also used as an entity path part: ``plane-ball``, ``ball1-ball2``."""
        return f"{self.first}-{self.second}"


@dataclass(frozen=True)
class Event:
    """One impact or release, at the time the analysis (or the recorder) gives it.

    Attributes:
        t_ns: its simulation time, ns (the table's `impact_t_s` / `release_t_s`).
        kind: ``impact`` or ``release``.
        pair: the bodies, when known.
        text: what the event log shows: one short line.
        details: every number behind it (the analysis row's, the log's velocities), shown
            one click away (the event's `details` in the viewer's selection panel).
        e_velocity: the restitution the text shows (`physics.e_velocity`), when measured.
    """

    t_ns: int
    kind: str
    pair: Pair | None
    text: str
    details: str = ""
    e_velocity: float | None = None


def pairs(run: RunLog) -> list[Pair]:
    """The pairs of parties with a contact episode in the log, in order of their first."""
    out: dict[Pair, None] = {}
    for ep in run.impacts.sort("onset_ns").iter_rows(named=True):
        out.setdefault(_pair(ep), None)
    return list(out)


def _pair(ep: Mapping[str, object]) -> Pair:
    """An episode's pair: a surface first (as the bounces name it), else the recorder's order."""
    if ep["kind2"] == "surface":
        return Pair(str(ep["side2"]), str(ep["side1"]))
    return Pair(str(ep["side1"]), str(ep["side2"]))


def log_events(run: RunLog) -> list[Event]:
    """Impact and release events of the log's contact episodes, at the recorder's onset and
    release: v_in at the impact, e = -v_out / v_in (the analysis' e_velocity, the same
    numbers) at the release, every number of the episode one click away."""
    events = []
    w_c, w_r = pl.col("work_compression_J"), pl.col("work_restitution_J")
    episodes = run.impacts.with_columns(
        physics.e_velocity(pl.col("v_in_mps"), pl.col("v_out_mps")).alias("e_velocity"),
        physics.e_energy(w_c, w_r, ~pl.col("open")).alias("e_energy"),
    )
    for ep in episodes.iter_rows(named=True):
        pair = _pair(ep)
        v_in, v_out = float(ep["v_in_mps"]), float(ep["v_out_mps"])
        details = f"v_in = {v_in:.4g} m/s, v_out = {v_out:.4g} m/s"
        if ep["e_energy"] is not None:
            details += (
                f", e_energy = {ep['e_energy']:.4g} (work {ep['work_compression_J']:.4g} J in, "
                f"{ep['work_restitution_J']:.4g} J out)"
            )
        text = f"impact {pair.name}: v_in = {v_in:.3g} m/s"
        events.append(Event(int(ep["onset_ns"]), "impact", pair, text, details))
        if not ep["open"] and v_in < 0:
            e = float(ep["e_velocity"])
            text = f"release {pair.name}: e_velocity = {e:.3g}"
            events.append(Event(int(ep["release_ns"]), "release", pair, text, details, e))
    return sorted(events, key=lambda e: e.t_ns)


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


def analysis_events(run: RunLog, tables: Mapping[str, pl.DataFrame]) -> list[Event] | None:
    """Events from the analysis rows of this run (None when no table has a row for it).

    Each row gives an impact at `impact_t_s` and, when not null, a release at `release_t_s`.
    The texts carry the row's numbers; the pair is the log's episode that starts then.
    """
    rows = [
        (name, row)
        for name, frame in tables.items()
        for row in frame.filter(pl.col("run_id") == run.run_id).iter_rows(named=True)
    ]
    if not rows:
        return None
    onsets = run.impacts["onset_ns"].to_numpy()
    found = [_pair(ep) for ep in run.impacts.iter_rows(named=True)]
    only = found[0] if len(set(found)) == 1 else None
    events = []
    for table, row in rows:
        if row.get("impact_t_s") is None:  # a row saying why nothing happened (no impact)
            continue
        near = np.flatnonzero(np.abs(onsets - float(row["impact_t_s"]) * 1e9) < 1e3)  # 1 us
        pair = found[int(near[0])] if near.size else only
        kind = table.removesuffix("s")
        number = row.get(kind)
        who = f"{kind}{f' {number}' if isinstance(number, int) else ''}"
        who = f"{who} {pair.name if pair else ''}".rstrip()
        numbers, e = _numbers(row), row.get("e_velocity")
        e = float(e) if isinstance(e, int | float) and not isinstance(e, bool) else None
        tail = "" if e is None else f": e_velocity = {e:.3g}"
        times = {"impact": row["impact_t_s"], "release": row.get("release_t_s")}
        for what, t_s in times.items():
            if t_s is not None:
                t_ns = round(float(t_s) * 1e9)
                events.append(Event(t_ns, what, pair, f"{what} {who}{tail}", numbers, e))
    return sorted(events, key=lambda e: e.t_ns)


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


def events_for(run: RunLog, tables: Mapping[str, pl.DataFrame] | None) -> list[Event]:
    """The analysis events of the run when `tables` has rows for it, else the log's."""
    found = analysis_events(run, tables) if tables else None
    return found if found is not None else log_events(run)
