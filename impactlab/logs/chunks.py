"""MCAP chunks assembled from whole arrays of messages, written through the official writer.

The official `mcap.writer.Writer` costs about 10 us per message in Python. Here a chunk's
message records, its message indexes and its chunk index are built from numpy arrays in a
few vectorised operations; the official writer still writes the header, schemas, channels,
metadata, attachments and the whole summary (statistics, chunk and summary indexes), so the
files are what it would write, message records sorted by time inside each chunk.

mcap has no public way to add a chunk built elsewhere: the writer's private state is reached
only through `impactlab.logs.mcap_internals` (the mcap version it was written for, and a test
that fails by name when it changes). `tests/logs/test_chunks.py` reads every file back with the
official reader and `rerun mcap check`.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import IO

import numpy as np
import zstandard
from isal.isal_zlib import crc32  # zlib's CRC-32, an order of magnitude faster
from mcap.opcode import Opcode
from mcap.records import Chunk, ChunkIndex
from mcap.writer import CompressionType, Writer

from impactlab.logs.codec import Template
from impactlab.logs.mcap_internals import WriterInternals

MESSAGE_OPCODE = int(Opcode.MESSAGE)
MESSAGE_INDEX_OPCODE = int(Opcode.MESSAGE_INDEX)
MESSAGE_HEADER = np.dtype(
    [("op", "u1"), ("len", "<u8"), ("ch", "<u2"), ("seq", "<u4"), ("lt", "<u8"), ("pt", "<u8")]
)
ZSTD_LEVEL = 1  # level 3 saves < 1 % here at 1.5x the time


@dataclass
class Block:
    """Messages of one channel: times (n,) int64 ns and payloads, one of
    - fixed-size bytes, (n, L) uint8;
    - a list of bytes;
    - with a `layout`, the doubles of each message in that fixed layout, (n, k) float64
      (encoded straight into the chunk, see `_records_dense`).
    """

    channel_id: int
    log_time: np.ndarray
    payloads: np.ndarray | Sequence[bytes]
    layout: Template | None = None

    @property
    def size(self) -> int:
        """Payload length of a fixed-size block, bytes."""
        if self.layout is not None:
            return self.layout.size
        assert isinstance(self.payloads, np.ndarray)
        return int(self.payloads.shape[1])

    def flat(self) -> tuple[np.ndarray, np.ndarray]:
        """Payload bytes concatenated, (total,) uint8, and each payload's length, (n,)."""
        if self.layout is not None:
            n, size = len(self.log_time), self.layout.size
            assert isinstance(self.payloads, np.ndarray)  # a layout's doubles, (n, k)
            return self.layout.encode(self.payloads).reshape(-1), np.full(n, size, np.int64)
        if isinstance(self.payloads, np.ndarray):
            n, size = self.payloads.shape
            return self.payloads.reshape(-1), np.full(n, size, dtype=np.int64)
        lengths = np.fromiter((len(p) for p in self.payloads), dtype=np.int64)
        return np.frombuffer(b"".join(self.payloads), dtype=np.uint8), lengths


class ChunkWriter:
    """An MCAP writer that takes messages as arrays, one chunk per `write_chunk` call."""

    def __init__(self, stream: IO[bytes], *, library: str, profile: str = "") -> None:
        self.writer = Writer(stream, use_chunking=False, compression=CompressionType.ZSTD)
        self.writer.start(profile=profile, library=library)
        self._internals = WriterInternals(self.writer)
        self._compressor = zstandard.ZstdCompressor(level=ZSTD_LEVEL)

    def write_chunk(self, blocks: Sequence[Block]) -> None:
        """Write one chunk holding every message of `blocks`, sorted by (time, block order)."""
        blocks = [b for b in blocks if len(b.log_time)]
        if not blocks:
            return
        dense = all(isinstance(b.payloads, np.ndarray) for b in blocks)
        records, index = _records_dense(blocks) if dense else _records(blocks)
        times = np.concatenate([b.log_time for b in blocks])
        start, end = int(times.min()), int(times.max())
        w = self._internals
        compressed = self._compressor.compress(records.data)
        chunk = Chunk(
            compression="zstd",
            data=compressed,
            message_start_time=start,
            message_end_time=end,
            uncompressed_crc=crc32(records),
            uncompressed_size=records.nbytes,
        )
        chunk_start, chunk_length = w.write_record(chunk)
        stream = w.stream
        offsets: dict[int, int] = {}
        position = stream.tell()
        index_bytes = []
        for channel_id, pairs in index.items():
            body = pairs.astype("<u8").tobytes()
            record = (
                bytes([MESSAGE_INDEX_OPCODE])
                + (2 + 4 + len(body)).to_bytes(8, "little")
                + channel_id.to_bytes(2, "little")
                + len(body).to_bytes(4, "little")
                + body
            )
            offsets[channel_id] = position
            position += len(record)
            index_bytes.append(record)
        stream.write(b"".join(index_bytes))
        w.add_chunk_index(
            ChunkIndex(
                message_start_time=start,
                message_end_time=end,
                chunk_start_offset=chunk_start,
                chunk_length=chunk_length,
                message_index_offsets=offsets,
                message_index_length=position - offsets[next(iter(offsets))],
                compression="zstd",
                compressed_size=len(compressed),
                uncompressed_size=records.nbytes,
            )
        )
        stats = w.statistics
        if stats.message_count == 0:
            stats.message_start_time = start
        stats.message_start_time = min(stats.message_start_time, start)
        stats.message_end_time = max(stats.message_end_time, end)
        stats.message_count += int(times.size)
        stats.chunk_count += 1
        for b in blocks:
            stats.channel_message_counts[b.channel_id] += len(b.log_time)

    def finish(self) -> None:
        """Write the summary and footer."""
        self.writer.finish()  # type: ignore[no-untyped-call]  # mcap: finish() has no hints


def _records_dense(blocks: Sequence[Block]) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """Records of fixed-size blocks, time-sorted, written straight into the chunk's bytes.

    The chunk's distinct times are cut into segments in which the same blocks have a
    message at every time; inside a segment each time's records are one row of a matrix,
    the blocks' records side by side. Each block fills its columns of the rows in a few
    strided assignments: the constant bytes (header, protobuf tags), the two times, and its
    doubles (`_RecordLayout`), so every byte of the chunk is written about once.
    """
    times, rows = _union_times(blocks)
    present = np.zeros((len(blocks), times.size), dtype=bool)
    for i, r in enumerate(rows):
        present[i, r] = True
    layouts = [_record_layout(b) for b in blocks]
    change = np.flatnonzero((present[:, 1:] != present[:, :-1]).any(axis=0)) + 1
    bounds = np.concatenate([[0], change, [times.size]]).tolist()
    out = np.empty(
        sum(len(b.log_time) * lay.size for b, lay in zip(blocks, layouts, strict=True)), np.uint8
    )
    index_parts: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    position = 0
    for lo, hi in itertools.pairwise(bounds):
        members = np.flatnonzero(present[:, lo]).tolist()
        m = hi - lo
        row_size = sum(layouts[i].size for i in members)
        segment = _Segment(out, position, m, row_size)
        offset = 0
        for i in members:
            first = int(np.searchsorted(rows[i], lo))
            layouts[i].fill(segment, offset, first)
            starts = np.arange(position + offset, position + row_size * m, row_size)
            pairs = (blocks[i].log_time[first : first + m], starts)
            index_parts.setdefault(blocks[i].channel_id, []).append(pairs)
            offset += layouts[i].size
        position += row_size * m
    index = {}
    for channel_id, parts in index_parts.items():
        times = np.concatenate([t for t, _ in parts])
        merged = np.stack([times, np.concatenate([s for _, s in parts])], axis=1)
        index[channel_id] = merged if len(parts) == 1 else merged[np.argsort(times, kind="stable")]
    return out, index


def _union_times(blocks: Sequence[Block]) -> tuple[np.ndarray, list[np.ndarray]]:
    """The blocks' distinct times, sorted, and where each block's messages fall in them.

    Usually one block's times hold every other's (a log's per-step channels share them);
    else the union is sorted.
    """
    longest = max(blocks, key=lambda b: len(b.log_time)).log_time
    rows = []
    for b in blocks:
        if b.log_time is longest:
            rows.append(np.arange(longest.size))
            continue
        r = np.searchsorted(longest, b.log_time)
        if not (r < longest.size).all() or not (longest[r] == b.log_time).all():
            times = np.unique(np.concatenate([b.log_time for b in blocks]))
            return times, [np.searchsorted(times, b.log_time) for b in blocks]
        rows.append(r)
    return longest, rows


@dataclass(frozen=True)
class _RecordLayout:
    """How one block's records are written into a row of a segment: the record's constant
    bytes (header and payload template), then runs of equally spaced doubles."""

    block: Block
    constant: np.ndarray  # (size,) uint8
    runs: tuple[tuple[int, int, int, int], ...]  # (first value, count, byte offset, stride)

    @property
    def size(self) -> int:
        return int(self.constant.size)

    def fill(self, segment: _Segment, offset: int, first: int) -> None:
        """Write the block's messages first.. into columns offset.. of every segment row."""
        block, m = self.block, segment.rows
        segment.matrix()[:, offset : offset + self.size] = self.constant
        times = block.log_time[first : first + m]
        segment.numbers(offset + 15, 2, 8, np.int64)[:] = times[:, None]  # log, publish time
        assert isinstance(block.payloads, np.ndarray)  # the dense path: fixed-size blocks
        payloads = block.payloads[first : first + m]
        if block.layout is None:
            segment.matrix()[:, offset + HEADER : offset + self.size] = payloads
            return
        for j, count, at, stride in self.runs:
            segment.numbers(offset + HEADER + at, count, stride)[:] = payloads[:, j : j + count]


HEADER = MESSAGE_HEADER.itemsize


def _record_layout(block: Block) -> _RecordLayout:
    header = np.zeros(1, dtype=MESSAGE_HEADER)
    header["op"] = MESSAGE_OPCODE
    header["len"] = block.size + (HEADER - 9)
    header["ch"] = block.channel_id
    if block.layout is None:
        payload = np.zeros(block.size, np.uint8)
        runs: tuple[tuple[int, int, int, int], ...] = ()
    else:
        payload = block.layout.template
        runs = _runs(block.layout.slots.tolist())
    constant = np.concatenate([header.view(np.uint8), payload])
    return _RecordLayout(block, constant, runs)


def _runs(slots: list[int]) -> tuple[tuple[int, int, int, int], ...]:
    """Slots cut into runs of equal spacing: (first value, count, first slot, spacing)."""
    runs: list[tuple[int, int, int, int]] = []
    j = 0
    while j < len(slots):
        stride = slots[j + 1] - slots[j] if j + 1 < len(slots) else 8
        count = 1
        while j + count < len(slots) and slots[j + count] - slots[j + count - 1] == stride:
            count += 1
        runs.append((j, count, slots[j], stride))
        j += count
    return tuple(runs)


@dataclass(frozen=True)
class _Segment:
    """`rows` rows of `row_size` bytes of `out`, from byte `start`."""

    out: np.ndarray
    start: int
    rows: int
    row_size: int

    def matrix(self) -> np.ndarray:
        """The rows as a (rows, row_size) uint8 view."""
        end = self.start + self.rows * self.row_size
        return self.out[self.start : end].reshape(self.rows, self.row_size)

    def numbers(self, at: int, count: int, stride: int, dtype: type = np.float64) -> np.ndarray:
        """A (rows, count) view of the little-endian 8-byte numbers at byte `at` + stride * j
        of every row (unaligned views are fine for numpy)."""
        return np.ndarray(
            shape=(self.rows, count),
            dtype=np.dtype(dtype).newbyteorder("<"),
            buffer=self.out,
            offset=self.start + at,
            strides=(self.row_size, stride),
        )


def _records(blocks: Sequence[Block]) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """The chunk's message records and, per channel, its (log_time, offset) index, (m, 2).

    The general path, for payloads of any length: a byte-level scatter in time order.
    """
    flats = [b.flat() for b in blocks]
    lengths = np.concatenate([f[1] for f in flats])
    data = np.concatenate([f[0] for f in flats])
    times = np.concatenate([b.log_time for b in blocks]).astype(np.int64)
    rank = np.concatenate([np.full(len(b.log_time), i) for i, b in enumerate(blocks)])
    channel = np.concatenate(
        [np.full(len(b.log_time), b.channel_id, dtype=np.uint16) for b in blocks]
    )
    src_start = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    order = np.lexsort((np.arange(times.size), rank, times))
    sizes = MESSAGE_HEADER.itemsize + lengths[order]
    dest = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    total = int(sizes.sum())
    out = np.empty(total, dtype=np.uint8)
    headers = np.zeros(times.size, dtype=MESSAGE_HEADER)
    headers["op"] = MESSAGE_OPCODE
    headers["len"] = lengths[order] + (MESSAGE_HEADER.itemsize - 9)
    headers["ch"] = channel[order]
    headers["lt"] = headers["pt"] = times[order]
    head_pos = dest[:, None] + np.arange(MESSAGE_HEADER.itemsize)
    out[head_pos] = headers.view(np.uint8).reshape(times.size, -1)
    sorted_len = lengths[order]
    before = np.concatenate([[0], np.cumsum(sorted_len)[:-1]])
    ramp = np.arange(int(sorted_len.sum())) - np.repeat(before, sorted_len)
    out[np.repeat(dest + MESSAGE_HEADER.itemsize, sorted_len) + ramp] = data[
        np.repeat(src_start[order], sorted_len) + ramp
    ]
    index = {}
    sorted_channel = channel[order]
    for channel_id in dict.fromkeys(b.channel_id for b in blocks):
        mine = sorted_channel == channel_id
        index[int(channel_id)] = np.stack([times[order][mine], dest[mine]], axis=1)
    return out, index
