"""Every body's state of a batch of runs in one frame, numbered by logged row (each run's
distinct logged times: a log written every N steps is read the same way), and per-run numbers."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import polars as pl

from impactlab.logs.load import RunLog
from impactlab.logs.messages import BODY_FIELDS


def per_run(runs: Sequence[RunLog], value: Callable[[RunLog], float]) -> pl.Expr:
    """A per-run number as an expression over the `run_id` column (run ids distinct)."""
    mapping = {run.run_id: float(value(run)) for run in runs}
    return pl.col("run_id").replace_strict(mapping, return_dtype=pl.Float64)


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


def at_times(t: np.ndarray, logged: pl.DataFrame, column: str) -> np.ndarray:
    """`column` of `logged` (t_ns, `column`) at each time of `t`; NaN where not logged."""
    times, values = logged["t_ns"].to_numpy(), logged[column].cast(pl.Float64).to_numpy()
    out = np.full(t.size, np.nan)
    if times.size:
        order = np.argsort(times, kind="stable")
        times, values = times[order], values[order]
        spot = np.clip(np.searchsorted(times, t), 0, times.size - 1)
        found = times[spot] == t
        out[found] = values[spot[found]]
    return out


def states_long(runs: Sequence[RunLog]) -> tuple[pl.DataFrame, pl.DataFrame]:
    """Every body's state of every run in one frame, and each run's logged rows.

    Returns:
        states: (run_id, body, row, t_ns, t_s, x .. wz), each run's rows together (in the
            order of `runs`), by body and time; `row` numbers the run's distinct logged
            times from 0.
        rows: (run_id, t_ns, row) of each run's logged times.
    """
    frames, bodies, numbers, ids, times = [], [], [], [], []
    for run in runs:
        mine = [(name, _by_time(run.bodies[name])) for name in sorted(run.bodies)]
        ts = [frame["t_ns"].to_numpy() for _, frame in mine]
        logged = ts[0] if ts else np.zeros(0, dtype=np.int64)
        if not all(_strictly_increasing(t) and np.array_equal(t, logged) for t in ts):
            logged = np.unique(np.concatenate(ts))
        for (name, frame), t in zip(mine, ts, strict=True):
            frames.append(frame)
            bodies.append(name)
            numbers.append(np.searchsorted(logged, t).astype(np.int64))
        ids.append(run.run_id)
        times.append(logged.astype(np.int64))
    run_ids = pl.Series("run_id", ids, dtype=pl.String)
    sizes = [t.size for t in times]
    rows = pl.DataFrame(
        [
            run_ids.gather(np.repeat(np.arange(len(ids)), sizes)),
            pl.Series("t_ns", np.concatenate(times) if times else [], dtype=pl.Int64),
            pl.Series(
                "row",
                np.concatenate([np.arange(t.size) for t in times]) if times else [],
                dtype=pl.Int64,
            ),
        ]
    )
    if not frames:
        schema = {"run_id": pl.String, "body": pl.String, "row": pl.Int64, "t_ns": pl.Int64}
        schema |= {"t_s": pl.Float64} | {c: pl.Float64 for c in BODY_FIELDS}
        return pl.DataFrame(schema=schema), rows
    names = pl.Series("body", bodies, dtype=pl.String)
    which = np.repeat(np.arange(len(frames)), [frame.height for frame in frames])
    states = pl.concat(frames).hstack(
        [names.gather(which), pl.Series("row", np.concatenate(numbers), dtype=pl.Int64)]
    )
    return states.select("run_id", "body", "row", pl.exclude("run_id", "body", "row")), rows


def state_blocks(states: pl.DataFrame) -> list[tuple[str, str, int, int]]:
    """The (run_id, body, first row, end row) of each body's block of `states_long`."""
    if not states.height:
        return []
    runs = states.select(pl.struct("run_id", "body").rle()).to_series().struct.unnest()
    ends = np.cumsum(runs["len"].to_numpy())
    keys = runs["value"].struct.unnest()
    return [
        (r, b, int(e - n), int(e))
        for r, b, n, e in zip(
            keys["run_id"].to_list(),
            keys["body"].to_list(),
            runs["len"].to_list(),
            ends,
            strict=True,
        )
    ]


def _by_time(frame: pl.DataFrame) -> pl.DataFrame:
    """A body's frame by time (as logged, unless a foreign log wrote it otherwise)."""
    return frame if frame["t_ns"].is_sorted() else frame.sort("t_ns")


def _strictly_increasing(t: np.ndarray) -> bool:
    return bool(t.size < 2 or (t[1:] > t[:-1]).all())


def state_at(
    states: pl.DataFrame, frame: pl.DataFrame, *, body: str, row: str, suffix: str
) -> pl.DataFrame:
    """Join each row of `frame` with the state of the body named in column `body` at the row
    number in column `row`; the state's columns get `suffix` (nulls where there is none)."""
    cols = ["t_ns", "x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz"]
    right = states.select(
        pl.col("body").alias(body),
        pl.col("row").alias(row),
        *[pl.col(c).alias(c + suffix) for c in cols],
    )
    return frame.join(right, on=[body, row], how="left")
