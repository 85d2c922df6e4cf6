"""The bodies' logged states looked up by (run, body, row) for many contacts at once."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from impactlab.analyze.measure.states import state_blocks

STATE = ("t_ns", "x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz")


@dataclass(frozen=True)
class States:
    """One body's state at one row for each interval: t (n,) s, x (n, 3) m, q (n, 4), v and
    w (n, 3) m/s and rad/s; NaN where there is none."""

    t: np.ndarray
    x: np.ndarray
    q: np.ndarray
    v: np.ndarray
    w: np.ndarray


class StateTable:
    """The bodies' logged states of one or more runs, looked up by (run, body, row) for many
    contacts at once."""

    def __init__(self, states: pl.DataFrame) -> None:
        # each (run, body) is one block of rows in `states_long`, its rows increasing: the
        # keys (block number, row) come sorted, and a lookup gathers only the rows it finds
        # (the general rank and a sort when the blocks are not so)
        self.states = states
        blocks = state_blocks(states)
        self.codes = {(r, b): float(i) for i, (r, b, _, _) in enumerate(blocks)}
        self.stride = (
            float(states.select(pl.col("row").max()).item() or 0) + 2 if states.height else 1.0
        )
        lengths = np.array([end - first for _, _, first, end in blocks], dtype=np.int64)
        code = np.repeat(np.arange(len(blocks), dtype=float), lengths)
        keys = code * self.stride + states["row"].to_numpy().astype(float)
        self.order: np.ndarray | None = None
        if len(self.codes) != len(blocks) or not bool((keys[1:] >= keys[:-1]).all()):
            coded = states.select(
                "run_id", "body", (pl.struct("run_id", "body").rank("dense") - 1).alias("code")
            )
            pairs = coded.unique("code", keep="first", maintain_order=True)
            self.codes = {
                (r, b): float(c)
                for r, b, c in zip(
                    *(pairs[k].to_list() for k in ("run_id", "body", "code")), strict=True
                )
            }
            keys = coded["code"].cast(pl.Float64).to_numpy() * self.stride
            keys = keys + states["row"].to_numpy().astype(float)
            self.order = np.argsort(keys, kind="stable")
            keys = keys[self.order]
        self.keys = keys

    def keys_of(self, runs: list[str], bodies: list[str | None], rows: np.ndarray) -> np.ndarray:
        """One number per (run, body, row); NaN where the body or row is missing or the body
        is unknown."""
        code = np.array(
            [
                self.codes.get((r, b), np.nan) if b else np.nan
                for r, b in zip(runs, bodies, strict=True)
            ]
        )
        keys: np.ndarray = code * self.stride + rows.astype(float)
        return keys

    def at(self, runs: list[str], bodies: list[str | None], rows: np.ndarray) -> States:
        """The state of each body at each row (NaN where the log has none)."""
        key = self.keys_of(runs, bodies, rows)
        out = np.full((key.size, len(STATE)), np.nan)
        if self.keys.size:
            spot = np.searchsorted(self.keys, np.nan_to_num(key, nan=-1.0))
            idx = np.clip(spot, 0, self.keys.size - 1)
            found = np.isfinite(key) & (self.keys[idx] == key)
            at = idx[found] if self.order is None else self.order[idx[found]]
            picked = self.states[at].select([pl.col(c).cast(pl.Float64) for c in STATE])
            out[found] = picked.to_numpy()
        return States(out[:, 0] / 1e9, out[:, 1:4], out[:, 4:8], out[:, 8:11], out[:, 11:14])
