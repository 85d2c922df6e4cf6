"""Chunks are decompressed into memory kept for the next chunk and file (`reader._scratch`):
what one load returned never changes when the next file is read, on any thread."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import paths

from impactlab.logs.load import load_log
from impactlab.logs.reader import read_mcap

GOLDEN = sorted((paths.GOLDEN / "logs").glob("*.mcap"))


def snapshot(run) -> list[np.ndarray]:
    """Copies of every value of a run's frames."""
    frames = [*run.bodies.values(), run.contacts, run.energy, run.clearance, run.events]
    return [np.array(f[c].to_list(), dtype=object) for f in frames for c in f.columns]


def same(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def test_frames_and_contents_do_not_change_when_the_next_file_is_read():
    assert len(GOLDEN) >= 3
    runs = [load_log(p) for p in GOLDEN]
    before = [snapshot(r) for r in runs]
    held = read_mcap(GOLDEN[0])
    pieces = [
        (t.copy(), np.array(d, copy=True)) for c in held.channels.values() for t, d in c.pieces
    ]
    for p in reversed(GOLDEN):  # every file read again, into the same memory
        load_log(p)
    assert all(same(snapshot(r), b) for r, b in zip(runs, before, strict=True))
    now = [(t, np.asarray(d)) for c in held.channels.values() for t, d in c.pieces]
    assert all(
        np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
        for a, b in zip(pieces, now, strict=True)
    )


def test_threads_read_into_their_own_memory():
    expected = {p: snapshot(load_log(p)) for p in GOLDEN}
    jobs = GOLDEN * 4

    def load(p):
        return p, snapshot(load_log(p))

    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(load, jobs))
    assert all(same(got, expected[p]) for p, got in results)
