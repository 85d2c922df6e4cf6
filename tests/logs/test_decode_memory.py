"""Chunks are decompressed into memory kept for the next file (`bounded.Arena`): what one
load returned, or a content still held, never changes when the next file is read, on any
thread."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import paths

from impactlab.logs.bounded import Arena
from impactlab.logs.load import load_log
from impactlab.logs.reader import read_mcap

GOLDEN = sorted((paths.GOLDEN / "logs").glob("*.mcap"))


def snapshot(run) -> list[np.ndarray]:
    """Copies of every value of a run's frames."""
    frames = [*run.bodies.values(), run.contacts, run.energy, run.clearance, run.events]
    return [np.array(f[c].to_list(), dtype=object) for f in frames for c in f.columns]


def same(a: list[np.ndarray], b: list[np.ndarray]) -> bool:
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def test_frames_do_not_change_when_the_next_file_is_read():
    assert len(GOLDEN) >= 3
    runs = [load_log(p) for p in GOLDEN]
    before = [snapshot(r) for r in runs]
    for p in reversed(GOLDEN):  # every file read again, into the same memory
        load_log(p)
    assert all(same(snapshot(r), b) for r, b in zip(runs, before, strict=True))
    assert Arena._kept.buffer is not None  # the memory is kept for the next read


def test_memory_still_viewed_is_not_reused():
    held = read_mcap(GOLDEN[0], reuse_memory=True)
    views = [
        (t.copy(), np.array(d, copy=True))
        for c in held.channels.values()
        for t, d in c.pieces
        if not isinstance(d, list)
    ]
    assert views  # payloads read through views into the kept memory
    for p in GOLDEN[1:]:
        load_log(p)
    now = [
        (t, np.asarray(d))
        for c in held.channels.values()
        for t, d in c.pieces
        if not isinstance(d, list)
    ]
    assert all(
        np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
        for a, b in zip(views, now, strict=True)
    )


def test_threads_read_into_their_own_memory():
    expected = {p: snapshot(load_log(p)) for p in GOLDEN}
    jobs = GOLDEN * 4

    def load(p):
        return p, snapshot(load_log(p))

    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(load, jobs))
    assert all(same(got, expected[p]) for p, got in results)
