"""A chunk's message indexes checked against the chunk, and each channel's payloads in it.

Message indexes carry no CRC, the chunk does: every record an index points at must be a
message of that channel at that time, with a payload inside the chunk. A recorder writes
each channel's messages evenly spaced in a chunk (one per step, all of one length): those
are checked through strided views of their headers and their payloads handed on as views
into the chunk; any other layout is checked and copied after one gather.
"""

from __future__ import annotations

import itertools

import numpy as np
from mcap.opcode import Opcode

OP_MESSAGE = int(Opcode.MESSAGE)
MESSAGE_HEADER_SIZE = 1 + 8 + 2 + 4 + 8 + 8  # opcode, length, channel, sequence, two times

_HEADER = np.dtype(
    {
        "names": ["op", "length", "channel", "log_time"],
        "formats": ["u1", "<u8", "<u2", "<u8"],
        "offsets": [0, 1, 9, 15],
        "itemsize": MESSAGE_HEADER_SIZE,
    }
)


GATHER_BLOCK_BYTES = 64 << 10
"""Records gathered into given memory go through blocks of this size (freed memory of the
heap, written before: fresh memory costs a page fault per 4 KiB page)."""

_SAME = np.dtype(  # op, length and channel (bytes 0-10 of a message record), in two words
    {"names": ["start", "end"], "formats": ["<u8", "<u4"], "offsets": [0, 7], "itemsize": 11}
)


def gather_records(
    raw: bytes | memoryview | np.ndarray,
    starts: np.ndarray,
    size: int,
    room: bytearray | memoryview | None = None,
) -> np.ndarray:
    """The `size` bytes at each offset `starts` of `raw` (every offset must leave `size`
    bytes), (n, size) uint8 (into `room`, writable memory of n * size bytes, when given:
    memory written before costs no page faults). Offsets in a few runs of even spacing, as
    a recorder's chunks hold a channel's records, are copied run by run, others gathered."""
    if size == 0:
        return np.empty((len(starts), 0), dtype=np.uint8)
    runs = _even_runs(starts)
    if runs is not None:  # a few runs of evenly spaced records: one strided copy each
        n = len(starts)
        out = np.empty((n, size), np.uint8) if room is None else np.frombuffer(room, np.uint8)
        out = out.reshape(n, size)
        for lo, hi, step, first in runs:
            view = np.ndarray((hi - lo, size), np.uint8, raw, first, (step, 1))
            out[lo:hi] = view
        return out
    row = np.dtype((np.void, size))
    whole = np.ndarray((len(raw) - size + 1,), dtype=row, buffer=raw, strides=(1,))
    if room is None:
        gathered: np.ndarray = whole[starts].view(np.uint8).reshape(len(starts), size)
        return gathered
    out = np.frombuffer(room, dtype=row)
    step = max(1, GATHER_BLOCK_BYTES // size)
    for at in range(0, len(starts), step):  # each block's copy reuses the last one's memory
        out[at : at + step] = whole[starts[at : at + step]]
    result: np.ndarray = out.view(np.uint8).reshape(len(starts), size)
    return result


MAX_RUNS_SHARE = 16
"""Records are copied run by run when there are at most one run per this many records
(numpy's gather costs about 60 ns per record, a strided copy a few us per run)."""


def _even_runs(starts: np.ndarray) -> list[tuple[int, int, int, int]] | None:
    """`starts` cut into runs of equal spacing, [(first, end, spacing, first offset)], or
    None when there are many."""
    n = len(starts)
    if n < 2 * MAX_RUNS_SHARE:
        return None
    at = starts.astype(np.int64, copy=False)
    steps = np.diff(at)
    change = np.flatnonzero(steps[1:] != steps[:-1]) + 2  # a run ends at the element before
    if len(change) * MAX_RUNS_SHARE > n:
        return None
    bounds = [0, *change.tolist(), n]
    runs = []
    for lo, hi in itertools.pairwise(bounds):
        if hi > lo:
            runs.append((lo, hi, int(steps[lo]) if hi - lo > 1 else 0, int(at[lo])))
    return runs


def checked_index(
    raw: bytes | memoryview, channel_id: int, pairs: np.ndarray
) -> tuple[np.ndarray, np.ndarray, int] | None:
    """(offsets, payload lengths, step) of one channel's indexed records in a chunk, or None
    unless every one is a whole message of `channel_id` at its indexed time.

    `pairs`: the index's (log_time, offset) rows, uint64. `step`: the constant distance
    between the records when they are evenly spaced and of one length (as a recorder writes
    them; they are then checked through strided views), else 0 (checked after a gather).
    """
    size, n = len(raw), len(pairs)
    first = int(pairs[0, 1])
    step = int(pairs[1, 1]) - first if n > 1 else MESSAGE_HEADER_SIZE
    even = (
        step >= MESSAGE_HEADER_SIZE
        and first + step * (n - 1) + MESSAGE_HEADER_SIZE <= size
        and bool((pairs[:, 1] == np.arange(first, first + step * n, step, dtype=np.uint64)).all())
    )
    if even:
        same = np.ndarray((n,), _SAME, buffer=raw, offset=first, strides=(step,))
        if (same["start"] == same["start"][0]).all() and (same["end"] == same["end"][0]).all():
            # op, length and channel as in the first record, which is checked alone
            header = np.ndarray((n,), _HEADER, buffer=raw, offset=first, strides=(step,))
            op, length, channel, _ = header[0].item()
            last_end = first + step * (n - 1) + 9 + length
            if (
                op != OP_MESSAGE
                or channel != channel_id
                or length < MESSAGE_HEADER_SIZE - 9
                or last_end > size
            ):
                return None
            if not (header["log_time"] == pairs[:, 0]).all():
                return None
            lengths = np.full(n, length - (MESSAGE_HEADER_SIZE - 9), dtype=np.int64)
            return pairs[:, 1].astype(np.int64), lengths, step
    offsets = pairs[:, 1].astype(np.int64)
    if (offsets < 0).any() or offsets.max() + MESSAGE_HEADER_SIZE > size:
        return None
    header = gather_records(raw, offsets, MESSAGE_HEADER_SIZE).view(_HEADER).reshape(-1)
    lengths = header["length"].astype(np.int64) - (MESSAGE_HEADER_SIZE - 9)
    # a length >= 2^63 reads as negative; otherwise every payload must end inside the chunk
    if lengths.min() < 0 or (offsets + lengths).max() + MESSAGE_HEADER_SIZE > size:
        return None
    agrees = (
        (header["op"] == OP_MESSAGE).all()
        and (header["channel"] == channel_id).all()
        and (header["log_time"] == pairs[:, 0]).all()
    )
    return (offsets, lengths, 0) if agrees else None


def add_pieces(
    pieces: list[tuple[np.ndarray, np.ndarray | list[bytes]]],
    raw: bytes | memoryview,
    times: np.ndarray,
    starts: np.ndarray,
    lengths: np.ndarray,
    step: int,
) -> None:
    """A chunk's messages of one channel, one piece per payload length (in index order):
    read-only views into the chunk when evenly spaced (`step` > 0), else gathered."""
    size = int(lengths[0])
    if step:
        shape, offset = (len(starts), size), int(starts[0])
        rows = np.ndarray(shape, np.uint8, buffer=raw, offset=offset, strides=(step, 1))
        pieces.append((times, rows))
        return
    if (lengths == size).all():
        pieces.append((times, gather_records(raw, starts, size)))
        return
    for size in np.unique(lengths).tolist():
        mine = lengths == size
        pieces.append((times[mine], gather_records(raw, starts[mine], size)))
