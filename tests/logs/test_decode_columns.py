"""The columns a log's frames repeat are built once (`decode.Columns`), and the fixed bytes of
a payload are checked through strided views (`codec.Template`): neither changes a value."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
from polars.testing import assert_series_equal

from impactlab.logs import messages
from impactlab.logs.decode import Columns, _constant


@pytest.mark.parametrize("sizes", [(7, 3, 7, 0), (3, 7, 5), (0, 4)])
def test_constant_columns_equal_columns_built_alone(sizes):
    columns = Columns()
    for n in sizes:
        got = columns.constant("run-a", n, "run_id")
        assert_series_equal(got, _constant("run-a", n, "run_id"), check_exact=True)
    assert_series_equal(
        columns.constant("other", 2, "body"), pl.Series("body", ["other"] * 2), check_exact=True
    )


def test_time_columns_are_shared_only_between_equal_times():
    columns = Columns()
    t = np.arange(0, 50, 5, dtype=np.int64)
    ns, s = columns.times(t)
    assert ns.to_list() == t.tolist() and s.to_list() == (t / 1e9).tolist()
    assert columns.times(t.copy())[0] is ns  # equal times: the same columns
    other = t.copy()
    other[-1] += 1
    ns2, s2 = columns.times(other)
    assert ns2 is not ns and ns2.to_list() == other.tolist()
    assert s2.to_list() == (other / 1e9).tolist()
    assert columns.times(t[:-1])[0].to_list() == t[:-1].tolist()  # a prefix is not equal


def test_contact_points_read_back_and_any_other_layout_is_refused():
    """`/contacts` payloads: points of three rows read back as written; a payload with any
    tag or length byte changed (another writer's layout) is not read this way."""
    rng = np.random.default_rng(3)
    row = np.array([0, 0, 1, 4, 4, 4])
    sides = rng.integers(-3, 50, (row.size, 2))
    values = rng.normal(size=(row.size, len(messages.POINT_FIELDS)))
    payloads = messages.contact_payloads(row, sides, values)
    assert [len(p) // messages.POINT_RECORD.itemsize for p in payloads] == [2, 1, 3]
    found = messages.contact_points(payloads)
    assert found is not None
    records, counts = found
    assert counts.tolist() == [2, 1, 3]
    assert np.array_equal(records["geom1"], sides[:, 0])
    assert np.array_equal(np.stack([records[f] for f in messages.POINT_FIELDS], 1), values)
    fixed = [n for n in messages.POINT_RECORD.names if n.startswith("t_") or n in ("tag", "len")]
    for name in fixed:
        bad = np.frombuffer(payloads[2], messages.POINT_RECORD).copy()
        bad[1][name] ^= 0x40
        assert messages.contact_points([payloads[0], bad.tobytes()]) is None, name


@pytest.mark.parametrize(
    "layout",
    [
        messages.body_state(),
        messages.energy(),
        messages.clearance(3),
        messages.work(),
    ],
    ids=["body", "energy", "clearance", "work"],
)
def test_every_fixed_byte_changed_is_another_layout(layout):
    n = 40
    values = np.arange(n * layout.slots.size, dtype=np.float64).reshape(n, -1)
    payloads = layout.encode(values)
    strided = np.zeros((n, layout.size + 7), np.uint8)[:, 3 : 3 + layout.size]  # rows apart
    strided[:] = payloads
    assert np.array_equal(layout.decode(strided), values)
    for at in np.flatnonzero(layout.fixed).tolist():
        bad = strided.copy()
        bad[n // 2, at] ^= 0x40
        assert layout.decode(bad) is None, at
    free = np.flatnonzero(~layout.fixed)  # the doubles' bytes: any value is a value
    changed = payloads.copy()
    changed[:, free] ^= 0x01
    assert layout.decode(changed) is not None


@pytest.mark.parametrize("kind", ["sorted", "runs", "backwards", "one"])
def test_records_copied_run_by_run_equal_the_gathered_ones(kind):
    """`gather_records` copies runs of evenly spaced records with one strided copy each
    (as a recorder's chunks hold them), any other offsets with one gather: same bytes."""
    from impactlab.logs import chunk_index

    rng = np.random.default_rng(len(kind))
    raw = rng.integers(0, 256, 100_000).astype(np.uint8)
    size, n = 37, 300
    if kind == "sorted":
        starts = np.sort(rng.integers(0, raw.size - size, n))
    elif kind == "runs":
        steps = np.repeat(rng.integers(0, 200, 4), n // 4)
        starts = np.concatenate([[5], 5 + np.cumsum(steps)])[:n]
    elif kind == "backwards":
        starts = np.arange(n)[::-1] * 91
    else:
        starts = np.full(n, 17)
    starts = starts.astype(np.uint64)
    want = np.stack([raw[s : s + size] for s in starts.tolist()])
    room = bytearray(n * size)
    assert np.array_equal(chunk_index.gather_records(raw.tobytes(), starts, size), want)
    got = chunk_index.gather_records(memoryview(raw), starts, size, memoryview(room))
    assert np.array_equal(got, want)
    if kind != "sorted":
        assert chunk_index._even_runs(starts) is not None  # the run-by-run path was taken
