"""Analysis of one run: every quantity frame, and the run's one-row summary."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import polars as pl

from impactlab.analyze.measure.bounces import bounces, no_bounce_rows
from impactlab.analyze.measure.collisions import (
    COLLISION_SCHEMA,
    collisions,
    no_collision_rows,
    with_surroundings,
)
from impactlab.analyze.measure.contact_intervals import contact_rows, raw_intervals
from impactlab.analyze.measure.energy import run_energies
from impactlab.analyze.measure.flights import flight_rows, flights
from impactlab.analyze.measure.ground import Ground, references, run_ground
from impactlab.analyze.measure.impacts import approach_and_release, merge_chatter
from impactlab.analyze.measure.phases import energy_phases
from impactlab.analyze.measure.states import logged_interval_s, per_run, state_blocks, states_long
from impactlab.analyze.measure.summary import run_aggregates, summary_row
from impactlab.errors import LogError
from impactlab.logs.load import RunLog


@dataclass
class RunAnalysis:
    """Everything computed for one run.

    Attributes:
        run: the decoded log.
        states: every body's state (`states_long`).
        intervals: contacts of every pair, chatter merged (`impacts.merge_chatter`).
        energy: energy per body and total ("total" rows), full resolution.
        phases: flight and contact phases with energy drift and loss.
        bounces: one row per bounce of a body on a surface (rows with the reason for bodies
            without any).
        collisions: one row per body-body contact (rows with the reason when a collision was
            expected and none happened).
        summary: the run's row of the runs table.
        ground: the run's ground surfaces and clearances.
        energy_logged: rows of `energy` at full resolution and the most of one body, kept
            when `energy` is decimated (`impactlab.analyze.batch.slim`).
    """

    run: RunLog
    states: pl.DataFrame
    intervals: pl.DataFrame
    energy: pl.DataFrame
    phases: pl.DataFrame
    bounces: pl.DataFrame
    collisions: pl.DataFrame
    summary: dict[str, Any]
    ground: Ground | None = None
    energy_logged: tuple[int, int] = (0, 0)


def expects_collision(run: RunLog) -> bool:
    """Whether the run was meant to bring two bodies together (a separation stop rule)."""
    return run.separation_m is not None


def analyze_run(run: RunLog) -> RunAnalysis:
    """Compute energy, bounces, collisions and the summary row of one decoded log.

    Raises:
        LogError: the metadata the analysis needs (masses, sizes, gravity, ground, timestep,
            logging stride, integrator) is missing, damaged or contradicts the channels; the
            message names the key.
    """
    (result,) = analyze_runs([run])
    if isinstance(result, LogError):
        raise result
    return result


@dataclass(frozen=True)
class _Contacts:
    """One run's states and raw contact intervals with their impact and release speeds."""

    run: RunLog
    ground: Ground
    states: pl.DataFrame
    rows: pl.DataFrame
    raw: pl.DataFrame


def _check(run: RunLog) -> Ground:
    """The run's ground, once its metadata is known to be usable (else LogError)."""
    reason = run.unanalyzable()
    if reason is not None:
        raise LogError(str(run.path), reason)
    return run_ground(run)


def _contacts(
    runs: list[RunLog], grounds: dict[str, Ground]
) -> tuple[list[_Contacts], pl.DataFrame]:
    """The row-level part of the analysis of runs with usable metadata: states, rows and raw
    contacts with their impact and release speeds, each run's split out of the batch's; and
    the batch's states."""
    states, rows = states_long(runs)
    kinds: dict[tuple[tuple[str, ...], tuple[str, ...]], list[RunLog]] = {}
    for run in runs:  # runs with the same bodies and surfaces: their contacts tagged at once
        kinds.setdefault((tuple(run.bodies), tuple(grounds[run.run_id].surfaces)), []).append(run)
    steps = pl.concat(
        [contact_rows(group, surfaces, rows) for (_, surfaces), group in kinds.items()]
    )
    raw = approach_and_release(raw_intervals(steps, runs, rows), states, runs, grounds)
    states_of, rows_of, raw_of = _run_slices(states), by_run(rows), by_run(raw)
    parts = [
        _Contacts(
            run,
            grounds[run.run_id],
            states_of.get(run.run_id, states.clear()),
            rows_of.get(run.run_id, rows.clear()),
            raw_of.get(run.run_id, raw.clear()),
        )
        for run in runs
    ]
    return parts, states


def _run_slices(states: pl.DataFrame) -> dict[str, pl.DataFrame]:
    """`states_long` of several runs split by run (each run's rows are together: slices)."""
    spans: dict[str, list[int]] = {}
    for r, _, first, end in state_blocks(states):
        spans.setdefault(r, [first, end])[1] = end
    return {r: states.slice(first, end - first) for r, (first, end) in spans.items()}


def by_run(frame: pl.DataFrame) -> dict[str, pl.DataFrame]:
    """A frame of several runs split by run_id (each run's rows in their order): slices when
    each run's rows are together (the batch's frames are by run), else a partition."""
    if not frame.height:
        return {}
    blocks = frame["run_id"].rle()
    ids = blocks.struct.field("value").to_list()
    if len(set(ids)) != len(ids) or None in ids:
        return {str(k[0]): f for k, f in frame.partition_by("run_id", as_dict=True).items()}
    lengths = blocks.struct.field("len").to_list()
    ends = np.cumsum(lengths).tolist()
    return {r: frame.slice(e - n, n) for r, n, e in zip(ids, lengths, ends, strict=True)}


def analyze_runs(runs: Sequence[RunLog]) -> list[RunAnalysis | LogError]:
    """Analyze several decoded logs at once: `analyze_run` of each, in order.

    The frames of all runs are stacked and each step (states, contact rows, contact
    intervals and their speeds, chatter merged, flights, bounces, energy phases, summary
    aggregates) is one set of frame operations keyed by run_id, so that many short runs do
    not each pay polars' fixed cost per operation; the results are those of each run alone
    (to 1e-12 relative where a group's sum is taken in another order). The run ids must be
    distinct (`impactlab.analyze.batch.distinct_batches`). A log the analysis cannot read
    gives its `LogError` in its place.
    """
    if len({run.run_id for run in runs}) != len(runs):
        raise ValueError("analyze_runs needs distinct run ids (see distinct_batches)")
    out: list[RunAnalysis | LogError | None] = [None] * len(runs)
    ready: list[int] = []
    grounds: dict[str, Ground] = {}
    for i, run in enumerate(runs):
        try:
            grounds[run.run_id] = _check(run)
            ready.append(i)
        except LogError as exc:
            out[i] = exc
    if ready:
        good = [runs[i] for i in ready]
        for i, a in zip(ready, _batch_or_each(good, grounds), strict=True):
            out[i] = a
    return [r for r in out if r is not None]


def _batch_or_each(runs: list[RunLog], grounds: dict[str, Ground]) -> list[RunAnalysis | LogError]:
    """The runs analyzed together; if that fails (one's metadata fails on the way, or runs
    whose frames cannot be stacked), each on its own, so that an error is that run's alone."""
    try:
        return list(_analyze_contacts(*_contacts(runs, grounds)))
    except LogError as exc:
        if len(runs) == 1:
            return [exc]
    except Exception:  # a run alone raises it again, if it is one run's
        if len(runs) == 1:
            raise
    return [r for run in runs for r in _batch_or_each([run], grounds)]


def _analyze_contacts(parts: list[_Contacts], states: pl.DataFrame) -> list[RunAnalysis]:
    """The analyses of runs whose states and raw contacts are computed (`_contacts`), in
    their order (see `analyze_runs`)."""
    runs = [p.run for p in parts]
    contacts = merge_chatter(pl.concat([p.raw for p in parts])).with_columns(
        per_run(runs, logged_interval_s).alias("interval_s")
    )
    on_ground = (
        contacts.filter(pl.col("kind") == "ground")
        .sort("run_id", "body", "first_row")
        .with_columns(pl.int_range(pl.len()).over("run_id", "body").alias("contact"))
    )
    first: dict[str, dict[str, str]] = {}  # per run, each body's first ground contact's surface
    for r, b, s in zip(*(on_ground[c].to_list() for c in ("run_id", "body", "other")), strict=True):
        first.setdefault(r, {}).setdefault(b, s)
    contacts_of, empty_contacts = by_run(contacts), contacts.clear()
    start = _first_positions(states)
    grounds = {p.run.run_id: p.ground for p in parts}
    refs = {
        r.run_id: references(r, grounds[r.run_id], first.get(r.run_id, {}), start.get(r.run_id, {}))
        for r in runs
    }
    energies, total_of = run_energies(states, runs, grounds, refs)
    totals, in_contact = [], []
    for p in parts:
        total = total_of[p.run.run_id]
        totals.append(total)
        times = contact_times(contacts_of.get(p.run.run_id, empty_contacts), p.rows)
        in_contact.append(is_in_sorted(total["t_ns"].to_numpy(), times.to_numpy()))
    total_all = pl.concat(totals)
    phases = energy_phases(total_all, pl.Series(np.concatenate(in_contact), dtype=pl.Boolean))
    fl = flights(flight_rows(states, on_ground, runs, grounds))
    g_n = -(
        per_run(runs, lambda r: r.gravity[0]) * pl.col("nx_out")
        + per_run(runs, lambda r: r.gravity[1]) * pl.col("ny_out")
        + per_run(runs, lambda r: r.gravity[2]) * pl.col("nz_out")
    )
    articulated = [
        (r.run_id, b) for r in runs for b, i in r.body_info.items() if i.motion != "free"
    ]
    work = pl.concat([r.contact_work for r in runs])
    found = bounces(on_ground, fl, gravity_n=g_n, articulated=articulated, work=work)
    bnc = _with_no_bounce_rows(parts, found, on_ground)
    bounces_of, phases_of = by_run(bnc), by_run(phases)
    body_contacts = by_run(contacts.filter(pl.col("kind") == "body"))
    aggregates = run_aggregates(total_all, phases, bnc)
    no_collisions = pl.DataFrame(schema=COLLISION_SCHEMA)  # built once: 40 columns
    out = []
    for p in parts:
        run, rid = p.run, p.run.run_id
        names = [n for n in run.body_info if n in run.bodies]
        infos = {n: run.body_info[n] for n in names}
        col = no_collisions
        if rid in body_contacts:
            col = collisions(body_contacts[rid], p.states, infos)
            g = float(np.linalg.norm(run.gravity))
            links = frozenset(n for n, i in run.body_info.items() if i.motion != "free")
            col = with_surroundings(col, run.contacts, g, logged_interval_s(run), links)
        if col.is_empty() and len(names) >= 2 and expects_collision(run):
            col = no_collision_rows(
                rid,
                p.states,
                infos,
                f"no contact between the bodies in the {duration_s(p.states):.4g} s logged: "
                "the collision never happened, so 'after' (last logged state) equals 'before'",
            )
        mine_bounces = bounces_of.get(rid, bnc.clear())
        summary = summary_row(
            run,
            aggregates=aggregates,
            states=p.states,
            collisions=col,
            ground=bool(p.ground.surfaces),
        )
        out.append(
            RunAnalysis(
                run,
                p.states,
                contacts_of.get(rid, empty_contacts),
                energies[rid],
                phases_of.get(rid, phases.clear()),
                mine_bounces,
                col,
                summary,
                p.ground,
            )
        )
    return out


def _first_positions(states: pl.DataFrame) -> dict[str, dict[str, tuple[float, float, float]]]:
    """Per run and body, its first logged position (x, y, z)."""
    blocks = state_blocks(states)
    at = np.array([first for _, _, first, _ in blocks], dtype=np.int64)
    xyz = [states[c].to_numpy()[at] if at.size else np.empty(0) for c in ("x", "y", "z")]
    out: dict[str, dict[str, tuple[float, float, float]]] = {}
    for i, (r, b, _, _) in enumerate(blocks):
        out.setdefault(r, {})[b] = (float(xyz[0][i]), float(xyz[1][i]), float(xyz[2][i]))
    return out


def _with_no_bounce_rows(
    parts: list[_Contacts], bnc: pl.DataFrame, on_ground: pl.DataFrame
) -> pl.DataFrame:
    """The runs' bounces, with a row for each body of a run with a ground that has none,
    saying why (after the run's bounces)."""
    have = set(zip(bnc["run_id"].to_list(), bnc["body"].to_list(), strict=True))
    missing = [
        (p, name)
        for p in parts
        if p.ground.surfaces
        for name in p.run.body_info
        if name in p.run.bodies and (p.run.run_id, name) not in have
    ]
    if not missing:
        return bnc
    firsts = on_ground.group_by("run_id", "body", maintain_order=True).agg(
        pl.col("other", "row_b", "v_min_mps").first()
    )
    first = {(r["run_id"], r["body"]): r for r in firsts.to_dicts()}
    reasons = [
        (p.run.run_id, name, no_bounce_reason(first.get((p.run.run_id, name)), p.states))
        for p, name in missing
    ]
    return pl.concat([bnc, no_bounce_rows(reasons)]).sort("run_id", maintain_order=True)


def contact_times(contacts: pl.DataFrame, rows: pl.DataFrame) -> pl.Series:
    """t_ns of every logged row inside any contact (chatter merged), sorted."""
    if contacts.is_empty() or rows.is_empty():
        return pl.Series("t_ns", [], dtype=pl.Int64)
    row, t_ns = rows["row"].to_numpy(), rows["t_ns"].to_numpy()
    first, last = contacts["first_row"].to_numpy(), contacts["last_row"].to_numpy()
    size = int(max(row.max(), last.max())) + 2
    cover = np.zeros(size, dtype=np.int64)  # +1 where a contact starts, -1 after it ends
    np.add.at(cover, first, 1)
    np.add.at(cover, last + 1, -1)
    inside = np.cumsum(cover)[row] > 0
    return pl.Series("t_ns", np.sort(t_ns[inside]), dtype=pl.Int64)


def is_in_sorted(values: np.ndarray, sorted_: np.ndarray) -> np.ndarray:
    """`np.isin(values, sorted_)` for a sorted `sorted_`, by a binary search of each value."""
    if not sorted_.size:
        return np.zeros(values.shape, dtype=bool)
    spot = np.minimum(np.searchsorted(sorted_, values), sorted_.size - 1)
    found: np.ndarray = sorted_[spot] == values
    return found


def duration_s(states: pl.DataFrame) -> float:
    """Logged duration in s (0 when nothing was logged)."""
    return float(states.select(pl.col("t_s").max()).item() or 0.0) if states.height else 0.0


def no_bounce_reason(first: dict[str, Any] | None, states: pl.DataFrame) -> str:
    """Why a body on a run with a ground has no bounce, from its first ground contact (other,
    row_b, v_min_mps; None: it has none) and the run's states."""
    if first is None:
        return f"no contact with the ground in the {duration_s(states):.4g} s logged"
    if first["row_b"] is None:
        return (
            f"at rest, sliding or rolling on {first['other']} from the first logged step: "
            "no impact, no bounce"
        )
    return (
        f"touches {first['other']} no faster than v_min = {first['v_min_mps']:.3g} m/s and "
        "stays: a resting, sliding or rolling contact, no bounce"
    )
