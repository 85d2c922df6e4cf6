"""The fixed bytes of a payload are checked wherever they are (`messages.Template`) and a
contact's record read back as written: another layout is never misread."""

from __future__ import annotations

import numpy as np
import pytest

from impactlab.logs import messages


def test_contact_points_read_back_and_any_other_layout_is_refused():
    """`/contacts` payloads: points of three rows read back as written; a payload with any
    tag or length byte changed (another writer's layout) is not read this way."""
    rng = np.random.default_rng(3)
    row = np.array([0, 0, 1, 4, 4, 4])
    sides = rng.integers(-3, 50, (row.size, 2))
    values = rng.normal(size=(row.size, len(messages.POINT_FIELDS)))
    groups = messages.contact_payloads(row, sides, values)
    by_row = {
        int(r): p.tobytes() for rows, group in groups for r, p in zip(rows, group, strict=True)
    }
    assert sorted(by_row) == [0, 1, 4]
    payloads = [by_row[r] for r in sorted(by_row)]
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


@pytest.mark.parametrize("kind", ["sorted", "backwards", "one"])
def test_records_taken_at_offsets_are_the_bytes_there(kind):
    """`reader._take`: the bytes at each offset, gathered at once."""
    from impactlab.logs.reader import _take

    rng = np.random.default_rng(len(kind))
    raw = rng.integers(0, 256, 100_000).astype(np.uint8)
    size, n = 37, 300
    if kind == "sorted":
        starts = np.sort(rng.integers(0, raw.size - size, n))
    elif kind == "backwards":
        starts = np.arange(n)[::-1] * 91
    else:
        starts = np.full(n, 17)
    want = np.stack([raw[s : s + size] for s in starts.tolist()])
    assert np.array_equal(_take(memoryview(raw.tobytes()), starts, size), want)
