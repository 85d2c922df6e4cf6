"""A file's message indexes checked channel by channel over all its chunks at once.

`reader.read_mcap` first reads a file this way: the chunks that have message indexes are
kept until the end of the file, then each channel's records in all of them are checked
together and copied out in one step (one gather of its records, one set of comparisons),
instead of one set of numpy calls per channel and chunk. Chunks decompressed into one
buffer (`bounded.Arena`) are addressed in it directly. A channel whose records are not all
of one length goes through `chunk_index` chunk by chunk, as does a channel in one chunk
(its evenly spaced records then stay views into the chunk). Any disagreement between an
index and its chunk makes `gather_indexed` return False: the reader then reads the file
again chunk by chunk, which reports the damage and walks the chunk (`reader._gather`).
"""

from __future__ import annotations

import functools
from collections import defaultdict
from typing import Any

import numpy as np

from impactlab.logs.bounded import Arena
from impactlab.logs.chunk_index import (
    MESSAGE_HEADER_SIZE,
    OP_MESSAGE,
    add_pieces,
    checked_index,
    gather_records,
)

Chunk = tuple[Any, dict[int, np.ndarray]]  # uncompressed records, message indexes by channel


@functools.cache
def _head(size: int) -> np.dtype:
    """A message record of `size` bytes: op and length (bytes 0-7), length's last byte and
    channel (7-10), log time."""
    return np.dtype(
        {
            "names": ["start", "end", "log_time"],
            "formats": ["<u8", "<u4", "<u8"],
            "offsets": [0, 7, 15],
            "itemsize": size,
        }
    )


def _segments(raws: list[Any]) -> tuple[list[np.ndarray], list[int], list[int]]:
    """Per chunk: the index of the buffer it lies in, its offset there; and the buffers.

    A chunk that is a view of a larger buffer (the arena) is addressed in that buffer, so
    the chunks of one file decompressed into it are one array.
    """
    buffers: list[np.ndarray] = []
    owners: dict[int, int] = {}
    which, bases = [], []
    for raw in raws:
        owner: Any = raw.obj if isinstance(raw, memoryview) and raw.obj is not None else raw
        k = owners.get(id(owner))
        if k is None:
            k = owners[id(owner)] = len(buffers)
            buffers.append(np.frombuffer(owner, np.uint8))
        whole = buffers[k]
        base = np.frombuffer(raw, np.uint8).ctypes.data - whole.ctypes.data if len(raw) else 0
        if not 0 <= base <= whole.size - len(raw):  # not inside its owner: its own buffer
            k = len(buffers)
            buffers.append(np.frombuffer(raw, np.uint8))
            base = 0
        which.append(k)
        bases.append(base)
    return buffers, which, bases


def gather_indexed(
    chunks: list[Chunk],
    channels: dict[int, Any],
    skip_topics: frozenset[str],
    arena: Arena | None = None,
) -> bool:
    """Add every indexed message of `chunks` (in file order) to its channel's pieces; False,
    with nothing to be trusted in `channels`, if any index disagrees with its chunk.

    The records are copied into `arena` when given (memory written before: no page faults).
    """
    if not chunks:
        return True
    raws = [raw for raw, _ in chunks]
    buffers, which, bases = _segments(raws)
    parts: dict[int, list[tuple[int, np.ndarray]]] = defaultdict(list)
    for j, (_, indexes) in enumerate(chunks):
        for channel_id, pairs in indexes.items():
            if len(pairs) and channels[channel_id].topic not in skip_topics:
                parts[channel_id].append((j, pairs))
    found = []
    for channel_id, mine in parts.items():
        pieces = None
        if len(mine) > 1 and len({which[j] for j, _ in mine}) == 1:
            whole = buffers[which[mine[0][0]]]
            pieces = _together(whole, raws, bases, mine, channel_id, arena)
        if pieces is None:
            pieces = _chunk_by_chunk(raws, mine, channel_id)
            if pieces is None:
                return False
        found.append((channels[channel_id], pieces))
    for channel, pieces in found:
        channel.pieces += pieces
    return True


def _chunk_by_chunk(
    raws: list[Any], mine: list[tuple[int, np.ndarray]], channel_id: int
) -> list[Any] | None:
    """One channel's pieces, chunk by chunk (`chunk_index`); None if an index disagrees."""
    pieces: list[Any] = []
    for j, pairs in mine:
        checked = checked_index(raws[j], channel_id, pairs)
        if checked is None:
            return None
        offsets, lengths, step = checked
        add_pieces(pieces, raws[j], pairs[:, 0], offsets + MESSAGE_HEADER_SIZE, lengths, step)
    return pieces


def _together(
    whole: np.ndarray,
    raws: list[Any],
    bases: list[int],
    mine: list[tuple[int, np.ndarray]],
    channel_id: int,
    arena: Arena | None,
) -> list[Any] | None:
    """One channel's records in several chunks of one buffer, all of one length, as one
    piece [(times, payloads (n, L))]; None unless every record is a whole message of the
    channel at its indexed time, of the first record's length."""
    pairs = np.concatenate([p for _, p in mine]) if len(mine) > 1 else mine[0][1]
    counts = np.array([len(p) for _, p in mine], dtype=np.int64)
    sizes = np.array([len(raws[j]) for j, _ in mine], dtype=np.int64)
    first = int(mine[0][1][0, 1])
    if first + 9 > sizes[0]:
        return None
    at = bases[mine[0][0]] + first
    length = int.from_bytes(whole[at + 1 : at + 9].tobytes(), "little")
    size = 9 + length
    if size < MESSAGE_HEADER_SIZE or size > sizes.min():
        return None
    relative = pairs[:, 1]
    ends = np.cumsum(counts)
    if (np.maximum.reduceat(relative, ends - counts) > (sizes - size).astype(np.uint64)).any():
        return None  # a record would end past its chunk
    starts = relative.astype(np.int64)
    for (j, _), end, count in zip(mine, ends.tolist(), counts.tolist(), strict=True):
        if bases[j]:
            starts[end - count : end] += bases[j]  # offsets in the chunk -> in the buffer
    room = arena.take(len(starts) * size) if arena is not None else None
    records = gather_records(whole, starts, size, room)
    head = records.view(_head(size))[:, 0]
    if not (
        (head["start"] == OP_MESSAGE | (length << 8)).all()
        and (head["end"] == channel_id << 16).all()
        and (head["log_time"] == pairs[:, 0]).all()
    ):
        return None
    return [(pairs[:, 0], records[:, MESSAGE_HEADER_SIZE:])]
