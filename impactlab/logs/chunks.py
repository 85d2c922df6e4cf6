"""MCAP chunks built from whole arrays of messages, in a file mcap's Writer writes and sums up.

`Writer.add_message` costs about 10 us a message: a chunk's records and indexes are built in
a few numpy operations instead. mcap has no public way to add a chunk built elsewhere:
`ChunkWriter` is the one adapter, reaching into the two parts of the Writer's private state
its summary is made from (`PRIVATE`, as of mcap `MCAP_VERSION`).
"""

from __future__ import annotations

import itertools
import struct
from collections import deque
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import IO

import mcap
import numpy as np
import zstandard
from isal.isal_zlib import crc32  # zlib's CRC-32, an order of magnitude faster
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import AttachmentIndex, Chunk, ChunkIndex, Statistics
from mcap.writer import Writer

MCAP_VERSION = "1.6.0"
"""The mcap version `PRIVATE` was read from (tests/logs/test_chunks.py checks it)."""
PRIVATE = ("_Writer__statistics", "_Writer__chunk_indices", "_Writer__attachment_indexes")
HEAD = np.dtype(
    [("op", "u1"), ("len", "<u8"), ("ch", "<u2"), ("seq", "<u4"), ("lt", "<u8"), ("pt", "<u8")]
)
INDEX_HEAD = [("op", "u1"), ("len", "<u8"), ("ch", "<u2"), ("bytes", "<u4")]  # MESSAGE_INDEX
PENDING = 2  # chunks built and not written yet at most (memory is bounded)
THREADED_BYTES = 1 << 18  # smaller chunks are compressed and written by the caller
ZSTD_LEVEL = -1  # zstd's fast mode: on contact-heavy logs half level 1's time, 2-5 % larger


@dataclass(frozen=True)
class Block:
    """Messages of one channel: times (n,) int64 ns and payloads, (n, L) uint8 or a list;
    or of several channels at the same times (`channel_id` an array (C,), payloads (n, C, L)),
    written as C blocks one after the other would be, at a cost that does not grow with C
    (in a chunk of arrays only: a chunk with a list holds blocks of one channel)."""

    channel_id: int | np.ndarray
    log_time: np.ndarray
    payloads: np.ndarray | Sequence[bytes]

    @property
    def channels(self) -> list[int]:
        """The block's channel ids, one per column of its payloads."""
        ids: list[int] = np.atleast_1d(self.channel_id).tolist()
        return ids


class ChunkWriter:
    """mcap's Writer (`writer`), plus `write_chunk` and `attach`. Every schema and channel is
    registered (`channel`) before the first chunk, and the Writer's buffered records are
    written out (by `add_metadata`, `add_attachment`) before each chunk. Chunks are written
    by a thread of their own: `wait` before writing with `writer`, `close` at the end."""

    def __init__(self, stream: IO[bytes], *, library: str) -> None:
        self.stream = stream
        self.writer = Writer(stream, use_chunking=False, enable_data_crcs=False)
        missing = [name for name in PRIVATE if not hasattr(self.writer, name)]
        if missing:
            raise RuntimeError(
                f"mcap {mcap.__version__}: its Writer has no {', '.join(missing)}; impactlab "
                f"writes logs with mcap {MCAP_VERSION} (impactlab/logs/chunks.py)"
            )
        self.writer.start(profile="", library=library)
        self.statistics: Statistics = getattr(self.writer, PRIVATE[0])
        self.chunk_indexes: list[ChunkIndex] = getattr(self.writer, PRIVATE[1])
        self.attachment_indexes: list[AttachmentIndex] = getattr(self.writer, PRIVATE[2])
        self._schemas: dict[str, int] = {}
        self._compressor = zstandard.ZstdCompressor(level=ZSTD_LEVEL)
        self._thread: ThreadPoolExecutor | None = None  # started by the first chunk
        self._pending: deque[Future[None]] = deque()

    def channel(self, topic: str, schema: str, data: bytes, metadata: dict[str, str]) -> int:
        """Register a protobuf channel (and its schema, once); its id."""
        if self.statistics.chunk_count or self._pending:
            raise RuntimeError("channels are registered before the first chunk")
        if schema not in self._schemas:
            self._schemas[schema] = self.writer.register_schema(schema, "protobuf", data)
        return self.writer.register_channel(topic, "protobuf", self._schemas[schema], metadata)

    def attach(self, name: str, media_type: str, data: bytes) -> None:
        """Write an attachment as `Writer.add_attachment` does (times 0), its data written
        once and its CRC from isal: mcap's own copies a large model's data three times."""
        self.wait()
        texts = [len(t).to_bytes(4, "little") + t for t in (name.encode(), media_type.encode())]
        head = bytes(16) + b"".join(texts) + len(data).to_bytes(8, "little")  # times 0
        length = len(head) + len(data) + 4
        at = self.stream.tell()
        self.stream.write(bytes([Opcode.ATTACHMENT]) + length.to_bytes(8, "little") + head)
        self.stream.write(data)
        self.stream.write(crc32(data, crc32(head)).to_bytes(4, "little"))
        self.statistics.attachment_count += 1
        index = AttachmentIndex(at, 9 + length, 0, 0, len(data), name, media_type)
        self.attachment_indexes.append(index)

    def write_chunk(self, blocks: Sequence[Block]) -> None:
        """Write one chunk holding every message of `blocks`, sorted by (time, block order):
        its records are built here, compressed and written on the writer's thread (zstd and
        the file release the GIL: the caller goes on meanwhile), in order, unless it is
        small; a failure of that thread is raised by a later call or `wait`."""
        blocks = [b for b in blocks if len(b.log_time)]
        if not blocks:
            return
        dense = all(isinstance(b.payloads, np.ndarray) for b in blocks)
        records, index = _dense(blocks) if dense else _loose(blocks)
        times = np.concatenate([b.log_time for b in blocks])
        span = (int(times.min()), int(times.max()))
        if len(records) < THREADED_BYTES:  # a thread would cost more than it saves
            self.wait()
            self._write(records, index, span)
            return
        if self._thread is None:
            self._thread = ThreadPoolExecutor(1, thread_name_prefix="impactlab-chunks")
        while self._pending and (self._pending[0].done() or len(self._pending) >= PENDING):
            self._pending.popleft().result()  # at most PENDING chunks held
        self._pending.append(self._thread.submit(self._write, records, index, span))

    def wait(self) -> None:
        """Wait until every chunk given is written (raising the first failure)."""
        while self._pending:
            self._pending.popleft().result()

    def close(self) -> None:
        """End the writer's thread once the chunk it writes is written (drop the others)."""
        if self._thread is not None:
            self._thread.shutdown(wait=True, cancel_futures=True)
            self._thread = None
        self._pending.clear()

    def _write(self, records: np.ndarray, index: Index, span: tuple[int, int]) -> None:
        """Compress and write a chunk's records and its message indexes; count them in the
        summary."""
        start, end = span
        compressed = self._compressor.compress(records.data)
        chunk = Chunk(
            compression="zstd",
            data=compressed,
            message_start_time=start,
            message_end_time=end,
            uncompressed_crc=crc32(records),
            uncompressed_size=len(records),
        )
        builder = RecordBuilder()
        chunk.write(builder)
        chunk_at = self.stream.tell()
        self.stream.write(builder.end())  # type: ignore[no-untyped-call]
        index_at = position = self.stream.tell()
        stats = self.statistics
        stats.message_start_time = (
            min(stats.message_start_time, start) if stats.chunk_count else start
        )
        stats.message_end_time = max(stats.message_end_time, end)
        stats.chunk_count += 1
        message_indexes, starts = index.records()
        offsets = dict(zip(index.channels.tolist(), (position + starts).tolist(), strict=True))
        for channel_id, count in zip(index.channels.tolist(), index.counts.tolist(), strict=True):
            stats.channel_message_counts[channel_id] += count
        stats.message_count += len(index.pairs)
        position += len(message_indexes)
        self.stream.write(message_indexes.data)
        self.chunk_indexes.append(
            _ChunkIndex(
                message_start_time=start,
                message_end_time=end,
                chunk_start_offset=chunk_at,
                chunk_length=index_at - chunk_at,
                message_index_offsets=offsets,
                message_index_length=position - index_at,
                compression="zstd",
                compressed_size=len(compressed),
                uncompressed_size=len(records),
            )
        )


@dataclass(frozen=True)
class Index:
    """A chunk's message indexes: its channels (k,) ascending, each one's number of messages
    (k,), and their (log_time, offset) rows (n, 2), channel after channel."""

    channels: np.ndarray
    counts: np.ndarray
    pairs: np.ndarray

    def records(self) -> tuple[np.ndarray, np.ndarray]:
        """The MESSAGE_INDEX records, one per channel in order, as bytes (uint8), and where
        each starts in them: channels of the same number of messages side by side are
        written as one array of records."""
        sizes = 15 + 16 * self.counts  # INDEX_HEAD, then 16 bytes a row
        starts = np.cumsum(sizes) - sizes
        out = np.empty(int(sizes.sum()), np.uint8)
        change = np.flatnonzero(self.counts[1:] != self.counts[:-1]) + 1
        first = 0
        for lo, hi in itertools.pairwise([0, *change.tolist(), self.counts.size]):
            n = int(self.counts[lo])
            record = np.dtype([*INDEX_HEAD, ("rows", "<u8", (n, 2))])
            at = int(starts[lo])
            view = out[at : at + (hi - lo) * record.itemsize].view(record)
            view["op"], view["len"], view["ch"], view["bytes"] = (
                Opcode.MESSAGE_INDEX,
                6 + 16 * n,
                self.channels[lo:hi],
                16 * n,
            )
            view["rows"] = self.pairs[first : first + (hi - lo) * n].reshape(hi - lo, n, 2)
            first += (hi - lo) * n
        return out, starts


class _ChunkIndex(ChunkIndex):
    """mcap's ChunkIndex, written as its bytes at once: mcap writes an offset (one per
    channel: hundreds for a model of hundreds of bodies) with a Python call per field."""

    def write(self, stream: RecordBuilder) -> None:
        offsets = np.empty(len(self.message_index_offsets), [("id", "<u2"), ("at", "<u8")])
        offsets["id"] = list(self.message_index_offsets)
        offsets["at"] = list(self.message_index_offsets.values())
        times = (self.message_start_time, self.message_end_time)
        head = struct.pack(
            "<4QI", *times, self.chunk_start_offset, self.chunk_length, offsets.nbytes
        )
        stream.start_record(Opcode.CHUNK_INDEX)
        stream.write(head + offsets.tobytes() + struct.pack("<Q", self.message_index_length))
        stream.write_prefixed_string(self.compression)
        stream.write(struct.pack("<2Q", self.compressed_size, self.uncompressed_size))
        stream.finish_record()  # type: ignore[no-untyped-call]  # mcap has no hints


def _fill(
    out: np.ndarray, at: int, row: int, block: Block, times: np.ndarray, payloads: np.ndarray
) -> None:
    """Write `block`'s message records at `times` (payloads (n, C, L)) into `out`, the first
    at byte `at`, a row of C records every `row` bytes: header fields and payloads in place."""
    channels = np.atleast_1d(block.channel_id)
    record = np.dtype([("head", HEAD), ("data", np.uint8, payloads.shape[2:])])
    shape, strides = (len(times), channels.size), (row, record.itemsize)
    records = np.ndarray(shape, record, out, at, strides)
    head = records["head"]
    head["op"], head["len"], head["ch"] = Opcode.MESSAGE, record.itemsize - 9, channels
    head["seq"] = 0
    head["lt"] = head["pt"] = times[:, None]
    records["data"] = payloads


def _dense(blocks: Sequence[Block]) -> tuple[np.ndarray, Index]:
    """The records of blocks of fixed-size payloads, time-sorted, and per channel its index
    (log_time, offset) rows. The chunk's times are cut into segments in which the same blocks
    have a message at each time; a segment is a matrix, a row per time, each block's records
    side by side in its columns."""
    times = np.sort(np.concatenate([b.log_time for b in blocks]))
    times = times[np.r_[True, times[1:] != times[:-1]]]  # np.unique would import numpy.ma
    present = np.zeros((len(blocks), times.size), bool)
    for i, b in enumerate(blocks):
        present[i, np.searchsorted(times, b.log_time)] = True
    change = np.flatnonzero((present[:, 1:] != present[:, :-1]).any(axis=0)) + 1
    payloads = [
        np.asarray(b.payloads).reshape(len(b.log_time), len(b.channels), -1) for b in blocks
    ]
    record = [HEAD.itemsize + p.shape[2] for p in payloads]  # one message's
    sizes = [r * len(b.channels) for r, b in zip(record, blocks, strict=True)]
    out = np.empty(int(present.sum(axis=1) @ np.array(sizes)), np.uint8)
    index_channel, index_time, index_offset = [], [], []  # each record's
    position = 0
    for lo, hi in itertools.pairwise([0, *change.tolist(), times.size]):
        members = np.flatnonzero(present[:, lo]).tolist()
        row = sum(sizes[i] for i in members)
        column = 0
        for i in members:
            b, size = blocks[i], record[i]
            first = int(np.searchsorted(b.log_time, times[lo]))
            t = b.log_time[first : first + hi - lo]
            _fill(out, position + column, row, b, t, payloads[i][first : first + hi - lo])
            starts = position + column + row * np.arange(hi - lo)
            channels = np.atleast_1d(b.channel_id)  # (C,): a row of records per time
            index_channel.append(np.tile(channels, t.size))
            index_time.append(np.repeat(t, channels.size))
            index_offset.append((starts[:, None] + size * np.arange(channels.size)).ravel())
            column += sizes[i]
        position += (hi - lo) * row
    index = (np.concatenate(c) for c in (index_channel, index_time, index_offset))
    return out, _by_channel(*index)


def _by_channel(channel: np.ndarray, time: np.ndarray, offset: np.ndarray) -> Index:
    """Each channel's index rows (log_time, offset), in the order given."""
    order = np.argsort(channel, kind="stable")
    channel = channel[order]
    pairs = np.stack([time[order], offset[order]], axis=1)
    bounds = np.flatnonzero(np.r_[True, channel[1:] != channel[:-1], True])
    return Index(channel[bounds[:-1]], np.diff(bounds), pairs)


def _loose(blocks: Sequence[Block]) -> tuple[np.ndarray, Index]:
    """The records of blocks of one channel each with payloads of any length, time-sorted
    (block order within a time), and per channel its index (log_time, offset) rows."""
    times = np.concatenate([b.log_time for b in blocks])
    payloads = [bytes(p) for b in blocks for p in b.payloads]
    channel = np.concatenate([np.full(len(b.log_time), b.channel_id) for b in blocks])
    rank = np.concatenate([np.full(len(b.log_time), i) for i, b in enumerate(blocks)])
    order = np.lexsort((np.arange(times.size), rank, times))
    lengths = np.array([len(payloads[i]) for i in order.tolist()], np.int64)
    head = np.zeros(times.size, HEAD)
    head["op"], head["len"], head["ch"] = (
        Opcode.MESSAGE,
        lengths + HEAD.itemsize - 9,
        channel[order],
    )
    head["lt"] = head["pt"] = times[order]
    heads = head.tobytes()
    n = HEAD.itemsize
    records = b"".join(
        part
        for k, i in enumerate(order.tolist())
        for part in (heads[k * n : k * n + n], payloads[i])
    )
    starts = np.concatenate([[0], np.cumsum(lengths + n)[:-1]])
    return np.frombuffer(records, np.uint8), _by_channel(channel[order], times[order], starts)
