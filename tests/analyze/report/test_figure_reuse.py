"""Figures drawn fast: lines thinned without losing a peak (`decimate_lines`), and a run's
energy figure drawn into the figure kept from the last run shows what a new one would."""

from __future__ import annotations

import numpy as np
import polars as pl

from impactlab.analyze.report.decimate_lines import minmax_indices, thinned


def test_thinning_keeps_every_bins_extremes_and_a_one_sample_spike():
    rng = np.random.default_rng(3)
    y = np.cumsum(rng.normal(size=100_001))
    y[54_321] += 500.0  # a contact spike one sample wide
    t = np.arange(y.size) * 1e-4
    keep = minmax_indices(y, bins=1000)
    assert keep.size <= 2 * 1000 + 2 and np.all(np.diff(keep) > 0)
    assert {0, y.size - 1, 54_321} <= set(keep.tolist())
    tx, ty = thinned(t, y, bins=1000)
    assert ty.max() == y.max() and ty.min() == y.min() and tx[ty.argmax()] == t[54_321]
    k = -(-y.size // 1000)
    for start in range(0, y.size, k):  # every bin's lowest and highest point is drawn
        part = y[start : start + k]
        assert set(np.flatnonzero(part == part.max()) + start) & set(keep.tolist())
        assert set(np.flatnonzero(part == part.min()) + start) & set(keep.tolist())


def test_short_lines_and_lines_with_gaps_are_drawn_whole():
    assert minmax_indices(np.arange(4000.0), bins=2000).size == 4000
    gap = np.arange(10_000.0)
    gap[5000] = np.nan
    assert minmax_indices(gap, bins=100).size == 10_000


def _energy(run: str, drop: float, n: int = 3000) -> pl.DataFrame:
    t = np.linspace(0.0, 1.5, n)
    h = np.abs(drop - 4.9 * t**2)
    ke = 9.81 * (drop - h)
    body = pl.DataFrame({"body": "ball", "is_total": False, "t_s": t, "height_m": h})
    total = pl.DataFrame(
        {
            "body": "total",
            "is_total": True,
            "t_s": t,
            "ke_trans_J": ke,
            "ke_rot_J": 0.0 * t,
            "pe_J": 9.81 * h,
            "total_J": ke + 9.81 * h,
            "mujoco_total_J": ke + 9.81 * h + 0.01,
        }
    )
    return pl.concat([body, total], how="diagonal").with_columns(run_id=pl.lit(run))
