"""Analysis of runs: every quantity frame, and each run's one-row summary."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import polars as pl

from impactlab.analyze.measure.bounces import TARGET_SCHEMA, bounces, target_e
from impactlab.analyze.measure.collisions import (
    COLLISION_SCHEMA,
    collisions,
    no_collision_rows,
    with_surroundings,
)
from impactlab.analyze.measure.energy import run_energies
from impactlab.analyze.measure.episodes import episodes
from impactlab.analyze.measure.flights import flight_rows, flights
from impactlab.analyze.measure.ground import Ground, references, run_ground
from impactlab.analyze.measure.phases import WORK_COLUMNS, energy_phases
from impactlab.analyze.measure.states import at_times, by_run, per_run, state_blocks, states_long
from impactlab.analyze.measure.summary import duration_s, run_aggregates, summary_row
from impactlab.errors import LogError
from impactlab.logs.load import RunLog
from impactlab.logs.messages import WORK_FIELDS

ANALYZED_FORMAT = 3
"""Logs of this format on are analyzed: they carry the recorder's contact episodes and
energy budget (`/impacts`, `/energy/work`)."""


@dataclass
class RunAnalysis:
    """Everything computed for one run.

    Attributes:
        run: the decoded log.
        states: every body's state (`states_long`).
        intervals: the run's contact episodes (`episodes.episodes`).
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


def _check(run: RunLog) -> Ground:
    """The run's ground, once its metadata is known to be usable (else LogError)."""
    reason = run.unanalyzable()
    if reason is not None:
        raise LogError(str(run.path), reason)
    version = str(run.checked.values.get("log_format_version", ""))
    if not (version.isdigit() and int(version) >= ANALYZED_FORMAT):
        raise LogError(
            str(run.path),
            f"a log of format {version or 'unknown'}: the analysis needs the contact episodes "
            f"and energy budget of format {ANALYZED_FORMAT} on; record the run again (its "
            "spec is in the log: `impactlab info` shows it)",
        )
    return run_ground(run)


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
        return list[RunAnalysis | LogError](_analyze(runs, grounds))
    except LogError as exc:
        if len(runs) == 1:
            return [exc]
    except Exception:  # a run alone raises it again, if it is one run's
        if len(runs) == 1:
            raise
    return [r for run in runs for r in _batch_or_each([run], grounds)]


def _analyze(runs: list[RunLog], grounds: dict[str, Ground]) -> list[RunAnalysis]:
    """The analyses of runs whose metadata is usable, in their order (see `analyze_runs`)."""
    states, rows = states_long(runs)
    eps = episodes(runs, rows)
    on_ground = (
        eps.filter(pl.col("kind") == "ground")
        .sort("run_id", "body", "start_t_ns")
        .with_columns(pl.int_range(pl.len()).over("run_id", "body").alias("contact"))
    )
    first: dict[str, dict[str, str]] = {}  # per run, each body's first ground contact's surface
    for r, b, o in zip(*(on_ground[c].to_list() for c in ("run_id", "body", "other")), strict=True):
        first.setdefault(r, {}).setdefault(b, o)
    start = _first_positions(states)
    refs = {
        r.run_id: references(r, grounds[r.run_id], first.get(r.run_id, {}), start.get(r.run_id, {}))
        for r in runs
    }
    energies, total_of = run_energies(states, runs, grounds, refs)
    budget = pl.concat([_budget(run, total_of[run.run_id]) for run in runs])
    inside = np.concatenate([_inside(run, eps, total_of[run.run_id]) for run in runs])
    phases = energy_phases(budget, pl.Series(inside, dtype=pl.Boolean))
    fl = flights(flight_rows(states, on_ground, runs, grounds))
    g_n = -(
        per_run(runs, lambda r: r.gravity[0]) * pl.col("nx_out")
        + per_run(runs, lambda r: r.gravity[1]) * pl.col("ny_out")
        + per_run(runs, lambda r: r.gravity[2]) * pl.col("nz_out")
    )
    articulated = [
        (r.run_id, b) for r in runs for b, i in r.body_info.items() if i.motion != "free"
    ]
    targets = pl.DataFrame(
        [row for run in runs for row in _target_rows(run)], schema=TARGET_SCHEMA, orient="row"
    )
    found = bounces(on_ground, fl, gravity_n=g_n, articulated=articulated, targets=targets)
    states_of = by_run(states)
    bnc = _with_no_bounce_rows(runs, grounds, states_of, found, on_ground)
    bounces_of, phases_of, eps_of = by_run(bnc), by_run(phases), by_run(eps)
    aggregates = run_aggregates(pl.concat(list(total_of.values())), phases, bnc)
    no_collisions = pl.DataFrame(schema=COLLISION_SCHEMA)  # built once: many columns
    out = []
    for run in runs:
        rid = run.run_id
        mine = eps_of.get(rid, eps.clear())
        run_states = states_of.get(rid, states.clear())
        names = [n for n in run.body_info if n in run.bodies]
        infos = {n: run.body_info[n] for n in names}
        col = collisions(mine.filter(pl.col("kind") == "body"), infos)
        if col.is_empty():
            col = no_collisions
        else:
            g = float(np.linalg.norm(run.gravity))
            links = frozenset(n for n, i in run.body_info.items() if i.motion != "free")
            col = _with_targets(with_surroundings(col, mine, g, links), targets)
        # a separation stop rule: the run was meant to bring two bodies together
        if col.is_empty() and len(names) >= 2 and run.separation_m is not None:
            col = no_collision_rows(
                rid,
                run_states,
                infos,
                f"no contact between the bodies in the {duration_s(run_states):.4g} s logged: "
                "the collision never happened, so 'after' (last logged state) equals 'before'",
            )
        summary = summary_row(
            run,
            aggregates=aggregates,
            states=run_states,
            collisions=col,
            ground=bool(grounds[rid].surfaces),
        )
        out.append(
            RunAnalysis(
                run,
                run_states,
                mine,
                energies[rid],
                phases_of.get(rid, phases.clear()),
                bounces_of.get(rid, bnc.clear()),
                col,
                summary,
                grounds[rid],
            )
        )
    return out


def _target_rows(run: RunLog) -> list[tuple[Any, ...]]:
    """The run's calibrated pairs (`TARGET_SCHEMA` rows) by the parties their geoms belong
    to, as the log's contacts name them (both orders); a pair that never touched has none.
    Each speed range is widened by one step of gravity: the recorder takes the speed at a
    step, up to g dt from the speed the pair was designed for (a drop's first impact)."""
    if not run.contact_targets or run.contacts.is_empty():
        return []
    step = float(np.linalg.norm(run.gravity)) * run.timestep_s
    sides = run.contacts.select(
        geom=pl.concat_list("geom1", "geom2"), party=pl.concat_list("body1", "body2")
    )
    party: dict[str, str] = dict(sides.explode("geom", "party").unique().iter_rows())
    rows = []
    for t in run.contact_targets:
        a, b = party.get(t.geom1), party.get(t.geom2)
        if a is None or b is None or t.speed_range_mps is None:
            continue
        low, high = t.speed_range_mps[0] - step, t.speed_range_mps[1] + step
        target = (t.restitution, low, high, t.curve_speed_mps, t.curve_e)
        rows += [(run.run_id, a, b, *target), (run.run_id, b, a, *target)]
    return rows


def _with_targets(col: pl.DataFrame, targets: pl.DataFrame) -> pl.DataFrame:
    """Collisions with their pair's target e when the closing speed is in its speed range."""
    pairs = targets.rename({"body": "body1", "other": "body2"})
    closing = pl.col("v1n_before_mps") - pl.col("v2n_before_mps")
    return (
        col.drop("target_e")
        .join(pairs, on=["run_id", "body1", "body2"], how="left", maintain_order="left")
        .with_columns(target_e(closing).alias("target_e"))
        .select(col.columns)
    )


def _budget(run: RunLog, total: pl.DataFrame) -> pl.DataFrame:
    """The run's budget rows (run_id, t_ns, t_s, energy_J, `WORK_COLUMNS`) at its "total"
    energy rows: the bodies' energy and the rotor inertia's, without the springs' (their
    work is booked instead), and the work each kind of force did so far."""
    t = total["t_ns"].to_numpy()
    joints = run.joint_energy
    spring = at_times(t, joints, "potential") if joints.height else np.zeros(t.size)
    return total.select("run_id", "t_ns", "t_s").with_columns(
        pl.Series("energy_J", total["total_J"].to_numpy() - spring),
        *[
            pl.Series(c, at_times(t, run.work, k))
            for k, c in zip(WORK_FIELDS, WORK_COLUMNS, strict=True)
        ],
    )


def _inside(run: RunLog, eps: pl.DataFrame, total: pl.DataFrame) -> np.ndarray:
    """Whether the time from each "total" row of the run to the next overlaps any of its
    contact episodes: the contact phases then hold every step in contact, the flights none."""
    t = total["t_ns"].to_numpy()
    mine = eps.filter(pl.col("run_id") == run.run_id)
    first = np.maximum(np.searchsorted(t, mine["start_t_ns"].to_numpy(), "right") - 1, 0)
    last = np.searchsorted(t, mine["end_t_ns"].to_numpy(), "left") - 1
    keep = last >= first
    cover = np.zeros(t.size + 1, np.int64)
    np.add.at(cover, first[keep], 1)
    np.add.at(cover, last[keep] + 1, -1)
    inside: np.ndarray = np.cumsum(cover)[:-1] > 0
    return inside


def _first_positions(states: pl.DataFrame) -> dict[str, dict[str, tuple[float, float, float]]]:
    """Per run and body, its first logged position (x, y, z)."""
    at = [first for _, _, first, _ in state_blocks(states)]
    out: dict[str, dict[str, tuple[float, float, float]]] = {}
    for r, b, x, y, z in states[at].select("run_id", "body", "x", "y", "z").iter_rows():
        out.setdefault(r, {})[b] = (x, y, z)
    return out


def _with_no_bounce_rows(
    runs: list[RunLog],
    grounds: dict[str, Ground],
    states_of: dict[str, pl.DataFrame],
    bnc: pl.DataFrame,
    on_ground: pl.DataFrame,
) -> pl.DataFrame:
    """The runs' bounces, with a row for each body of a run with a ground that has none,
    saying why (after the run's bounces)."""
    have = set(zip(bnc["run_id"].to_list(), bnc["body"].to_list(), strict=True))
    missing = [
        (run, name)
        for run in runs
        if grounds[run.run_id].surfaces
        for name in run.body_info
        if name in run.bodies and (run.run_id, name) not in have
    ]
    if not missing:
        return bnc
    firsts = on_ground.group_by("run_id", "body", maintain_order=True).agg(
        pl.col("other", "initial", "v_min_mps").first()
    )
    first = {(r["run_id"], r["body"]): r for r in firsts.to_dicts()}
    reasons = [
        (
            run.run_id,
            name,
            no_bounce_reason(
                first.get((run.run_id, name)), states_of.get(run.run_id, pl.DataFrame())
            ),
        )
        for run, name in missing
    ]
    rows = pl.DataFrame(reasons, schema=["run_id", "body", "note"], orient="row")
    rows = rows.with_columns(complete=pl.lit(False))  # body and reason only
    return pl.concat([bnc, rows], how="diagonal").sort("run_id", maintain_order=True)


def no_bounce_reason(first: dict[str, Any] | None, states: pl.DataFrame) -> str:
    """Why a body on a run with a ground has no bounce, from its first ground contact (other,
    initial, v_min_mps; None: it has none) and the run's states."""
    if first is None:
        return f"no contact with the ground in the {duration_s(states):.4g} s logged"
    if first["initial"]:
        return (
            f"at rest, sliding or rolling on {first['other']} from the start: no impact, no bounce"
        )
    return (
        f"at rest, sliding or rolling on {first['other']}: it arrived no faster than "
        f"v_min = {first['v_min_mps']:.3g} m/s and stayed, no bounce"
    )
