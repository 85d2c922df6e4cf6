"""Free flights of each body between its ground contacts, and their apexes (docs/analysis.md)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import polars as pl

from impactlab.analyze.measure.ground import Ground
from impactlab.analyze.measure.states import state_blocks
from impactlab.logs.load import RunLog
from impactlab.physics import up_vector

APEX_TURN_FRACTION = 1e-3
"""A flight whose lowest point moves relative to the centre of mass by more than this
fraction of the apex height turns too much for its apex to measure e (0.05 % of e)."""
APEX_TURN_FLOOR_M = 1e-9
"""Offset changes below this (rounding) never count as turning."""
FLIGHT_SCHEMA = pl.Schema(
    {
        "run_id": pl.String,
        "body": pl.String,
        "flight": pl.Int64,
        "n_rows": pl.UInt32,
        "surface_before": pl.String,
        "surface_after": pl.String,
        "apex_t_s": pl.Float64,
        "apex_after_m": pl.Float64,
        "apex_before_m": pl.Float64,
        "reached": pl.Boolean,
        "turning_after": pl.Boolean,
        "turning_before": pl.Boolean,
    }
)


def flights(rows: pl.DataFrame | None) -> pl.DataFrame:
    """One row per flight of each body of each run, with its apex above the surfaces around it.

    Args:
        rows: `flight_rows` of one or more runs (concatenated); None: no rows.

    Returns:
        (run_id, body, flight, n_rows, surface_before (left), surface_after (landed on
        next), apex_t_s, apex_after_m, apex_before_m (above those surfaces at the apex),
        reached (the apex lies within the logged flight), turning_after, turning_before).
    """
    if rows is None or rows.is_empty():
        return pl.DataFrame(schema=FLIGHT_SCHEMA)
    g = pl.col("g").first()
    apex = pl.col("z_up").arg_max()
    w_apex = pl.col("w").gather(apex)
    # the apex is inside the flight unless the flight starts descending (a release at rest)
    inside = (apex > 0) | (w_apex > 0)
    rise = pl.when(g > 0).then(pl.when(inside).then(w_apex**2 / (2 * g)).otherwise(0.0))

    def height(side: str) -> pl.Expr:
        return (pl.col(f"c_{side}").gather(apex) + rise).first()

    def turn(side: str) -> pl.Expr:
        offset = pl.col("z_up") - pl.col(f"c_{side}")
        return (offset.max() - offset.min()).alias(f"offset_range_{side}")

    per = rows.group_by("run_id", "body", "flight", maintain_order=True).agg(
        pl.len().alias("n_rows"),
        pl.col("surface_before").first(),
        pl.col("surface_after").first(),
        pl.col("t_s").gather(apex).first().alias("apex_t_s"),
        height("before").alias("apex_after_m"),  # above the surface left
        height("after").alias("apex_before_m"),  # above the surface landed on next
        ((pl.col("w").last() <= 0) & (g > 0)).alias("reached"),
        turn("before"),
        turn("after"),
    )
    return (
        per.with_columns(
            (
                pl.col("offset_range_before")
                > APEX_TURN_FRACTION * pl.col("apex_after_m").abs() + APEX_TURN_FLOOR_M
            ).alias("turning_after"),
            (
                pl.col("offset_range_after")
                > APEX_TURN_FRACTION * pl.col("apex_before_m").abs() + APEX_TURN_FLOOR_M
            ).alias("turning_before"),
        )
        .select(list(FLIGHT_SCHEMA))
        .cast(FLIGHT_SCHEMA)
    )


def flight_rows(
    states: pl.DataFrame,
    contacts: pl.DataFrame,
    runs: Sequence[RunLog],
    grounds: Mapping[str, Ground],
) -> pl.DataFrame | None:
    """The logged rows of each body of each run outside its ground contacts, by run, body
    and row: (run_id, body, flight, row, t_s, z_up (centre height along -gravity), w
    (velocity along -gravity minus g h, h the half step `RunLog.half_step_s`),
    surface_before, c_before, surface_after, c_after (the surfaces around the flight and the
    clearances to them), g (|gravity|)); None when there are none.

    Args:
        states: `states_long` of the runs (ids distinct).
        contacts: their merged ground contacts (run_id, body, other, first_row, last_row).
        runs: the runs (gravity, integrator, timestep); grounds: their grounds, by run id.

    A row belongs to the latest contact that begins at or before it (the body's contacts by
    first row) unless it lies after that contact's last row: then it is in flight `contact
    + 1` (0 before the first), between the surface of that contact and the next one's.
    """
    blocks = state_blocks(states)
    if not blocks:
        return None
    by_id = {run.run_id: run for run in runs}
    per_run = {r: _vertical(by_id[r]) for r in {b[0] for b in blocks}}
    lengths = np.array([end - first for _, _, first, end in blocks])
    values = np.array([per_run[r] for r, _, _, _ in blocks])  # ux, uy, uz, w_shift, g
    extra = [
        pl.Series(k, np.repeat(values[:, i], lengths))
        for i, k in enumerate(("ux", "uy", "uz", "w_shift", "g"))
    ]
    ux, uy, uz = pl.col("ux"), pl.col("uy"), pl.col("uz")
    z_up = ux * pl.col("x") + uy * pl.col("y") + uz * pl.col("z")
    v_up = ux * pl.col("vx") + uy * pl.col("vy") + uz * pl.col("vz")
    cols = states.hstack(extra).select(
        "row", "t_ns", "t_s", z_up.alias("z_up"), (v_up - pl.col("w_shift")).alias("w"), "g"
    )
    arrays = {c: cols[c].to_numpy() for c in cols.columns}
    touch = contacts.sort("run_id", "body", "first_row")
    hits: dict[tuple[str, str], list[tuple[int, int, str]]] = {}
    for r, b, first, last, other in zip(
        *(touch[c].to_list() for c in ("run_id", "body", "first_row", "last_row", "other")),
        strict=True,
    ):
        hits.setdefault((r, b), []).append((first, last, other))
    names: list[str | None] = [None]  # the surfaces' names
    picks: list[np.ndarray] = []  # per block: its kept rows, and their flights
    flights_: list[np.ndarray] = []
    surfaces_before: list[np.ndarray] = []  # per block: the surfaces' codes, the clearances
    surfaces_after: list[np.ndarray] = []
    c_before: list[tuple[np.ndarray, np.ndarray]] = []
    c_after: list[tuple[np.ndarray, np.ndarray]] = []
    for r, b, start, end in blocks:
        mine = hits.get((r, b), [])
        row, t_ns = arrays["row"][start:end], arrays["t_ns"][start:end]
        first = np.array([h[0] for h in mine], dtype=np.int64)
        last = np.array([h[1] for h in mine], dtype=np.int64)
        contact = np.searchsorted(first, row, side="right") - 1
        keep = np.ones(row.size, dtype=bool)
        if first.size:
            keep = (contact < 0) | (row > last[np.maximum(contact, 0)])
        flight = contact[keep] + 1
        t_kept = t_ns[keep]
        picks.append(np.flatnonzero(keep) + start)
        flights_.append(flight)
        surfaces = [h[2] for h in mine]
        # flight j lies between contact j - 1 (the surface left) and contact j (landed on)
        for around, name_idx, clear in (
            ([None, *surfaces], surfaces_before, c_before),
            ([*surfaces, None], surfaces_after, c_after),
        ):
            codes = np.array([_code(names, n) for n in around], dtype=np.int64)
            name_idx.append(codes[flight])
            c = np.full(flight.size, np.nan)
            found = np.zeros(flight.size, dtype=bool)
            for i, name in enumerate(around):
                spot = flight == i
                if name is not None and spot.any():
                    c[spot], found[spot] = grounds[r].clearance_at(b, name, t_kept[spot])
            clear.append((c, found))
    at = np.concatenate(picks)
    if not at.size:
        return None
    block_of = np.repeat(np.arange(len(blocks)), [p.size for p in picks])
    run_ids = pl.Series("run_id", [blk[0] for blk in blocks], dtype=pl.String)
    bodies = pl.Series("body", [blk[1] for blk in blocks], dtype=pl.String)
    surface_names = pl.Series("surface", names, dtype=pl.String)

    def clearances(name: str, parts: list[tuple[np.ndarray, np.ndarray]]) -> pl.Series:
        values = np.concatenate([c for c, _ in parts])
        found = np.concatenate([f for _, f in parts])
        return pl.Series(name, values).scatter(np.flatnonzero(~found), None)

    return pl.DataFrame(
        [
            run_ids.gather(block_of),
            bodies.gather(block_of),
            pl.Series("flight", np.concatenate(flights_)),
            pl.Series("row", arrays["row"][at]),
            pl.Series("t_s", arrays["t_s"][at]),
            pl.Series("z_up", arrays["z_up"][at]),
            pl.Series("w", arrays["w"][at]),
            surface_names.gather(np.concatenate(surfaces_before)).alias("surface_before"),
            clearances("c_before", c_before),
            surface_names.gather(np.concatenate(surfaces_after)).alias("surface_after"),
            clearances("c_after", c_after),
            pl.Series("g", arrays["g"][at]),
        ]
    )


def _vertical(run: RunLog) -> tuple[float, float, float, float, float]:
    """A run's unit vector against gravity, the velocity shift g h and |g|."""
    g = float(np.linalg.norm(run.gravity))
    up = up_vector(run.gravity)
    return float(up[0]), float(up[1]), float(up[2]), g * run.half_step_s, g


def _code(names: list[str | None], name: str | None) -> int:
    """The index of `name` in `names`, appended when new."""
    if name not in names:
        names.append(name)
    return names.index(name)
