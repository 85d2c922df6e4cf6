"""Lines thinned for drawing without hiding a peak: each bin's lowest and highest point."""

from __future__ import annotations

import numpy as np

LINE_BINS = 2000
"""A line of more than twice this many points is drawn from this many bins' extremes
(a figure's axes are about 900 pixels wide: two bins or more per pixel column)."""


def minmax_indices(y: np.ndarray, bins: int = LINE_BINS) -> np.ndarray:
    """The indices of `y` to draw, in order: all of them for a short line (or one with a
    NaN: its gaps stay where they are), else the first and last point and the lowest and
    highest point of each of `bins` runs of consecutive points (so every peak stays)."""
    n = y.size
    if n <= 2 * bins or not np.isfinite(y).all():
        return np.arange(n)
    k = -(-n // bins)  # points per bin; the last bin is padded with the last point
    rows = np.concatenate([y, np.full(k * bins - n, y[-1])]).reshape(bins, k)
    start = np.arange(bins) * k
    lows = np.minimum(start + rows.argmin(axis=1), n - 1)
    highs = np.minimum(start + rows.argmax(axis=1), n - 1)
    return np.unique(np.concatenate([[0, n - 1], lows, highs]))


def thinned(x: np.ndarray, y: np.ndarray, bins: int = LINE_BINS) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) at `minmax_indices(y, bins)`."""
    keep = minmax_indices(y, bins)
    return (x, y) if keep.size == y.size else (x[keep], y[keep])
