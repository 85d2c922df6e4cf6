"""Walk an MCAP file's records and gather each channel's messages as arrays.

Top-level records are read one by one (a handful per file: header, schemas, channels,
metadata, chunks and their message indexes). Inside a chunk, the message indexes that
follow it give every message's offset, so a channel's messages are gathered with numpy
fancy indexing instead of one Python step per message; a chunk without indexes, or whose
indexes disagree with it (they carry no CRC), is walked record by record. Damage (truncation,
a bad CRC, an undecompressable chunk, an unreadable record) stops the walk: everything
complete before it is returned, with the problem.
"""

from __future__ import annotations

import contextlib
import io
import struct
import zlib
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import lz4.frame
import numpy as np
import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.records import Channel, Metadata, Schema

MAGIC = b"\x89MCAP0\r\n"
OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_MESSAGE_INDEX = 0x03, 0x04, 0x05, 0x06, 0x07
OP_METADATA, OP_DATA_END = 0x0C, 0x0F
MESSAGE_HEADER_SIZE = 1 + 8 + 2 + 4 + 8 + 8  # opcode, length, channel, sequence, two times
FOOTER_SIZE = 1 + 8 + 8 + 8 + 4  # opcode, length, summary start, summary offset start, CRC


@dataclass
class ChannelData:
    """One channel's messages, in pieces of equal-length payloads (n, L) or loose bytes."""

    topic: str
    schema: str
    metadata: dict[str, str]
    pieces: list[tuple[np.ndarray, np.ndarray | list[bytes]]] = field(default_factory=list)

    @property
    def count(self) -> int:
        """Number of messages."""
        return sum(len(t) for t, _ in self.pieces)


@dataclass
class McapContent:
    """What a walk found: channels with messages, metadata records, and any damage."""

    channels: dict[int, ChannelData]
    metadata: dict[str, dict[str, str]]
    problems: list[str]


class _Damage(Exception):
    pass


def read_mcap(path: Path, *, skip_topics: frozenset[str] = frozenset()) -> McapContent:
    """Gather every complete message and metadata record of an MCAP file.

    Messages on `skip_topics` are not gathered (their channels are still listed).

    Raises:
        ValueError: the file does not start with the MCAP magic bytes.
        OSError: the file cannot be read.
    """
    buf = memoryview(Path(path).read_bytes())
    if bytes(buf[:8]) != MAGIC:
        raise ValueError("not an MCAP file (bad magic bytes)")
    schemas: dict[int, str] = {}
    channels: dict[int, ChannelData] = {}
    metadata: dict[str, dict[str, str]] = {}
    problems: list[str] = []
    loose: dict[int, tuple[list[int], list[bytes]]] = defaultdict(lambda: ([], []))
    pos = 8
    pending: tuple[bytes, dict[int, np.ndarray] | None, int] | None = None
    try:
        while pos < len(buf):
            if pos + 9 > len(buf):
                raise _Damage(f"truncated at byte {pos}")
            op = buf[pos]
            length = int.from_bytes(buf[pos + 1 : pos + 9], "little")
            end = pos + 9 + length
            if end > len(buf):
                raise _Damage(f"truncated inside a record at byte {pos}")
            body = buf[pos + 9 : end]
            if op != OP_MESSAGE_INDEX and pending is not None:
                done, pending = pending, None
                _gather(done, schemas, channels, loose, skip_topics, problems)
            if op in (OP_SCHEMA, OP_CHANNEL):
                _definition(op, body, schemas, channels)
            elif op == OP_METADATA:
                m = Metadata.read(ReadDataStream(io.BytesIO(body)))
                metadata[m.name] = dict(m.metadata)
            elif op == OP_CHUNK:
                pending = (_decompress(body), {}, pos)
            elif op == OP_MESSAGE_INDEX and pending is not None:
                channel_id = int.from_bytes(body[0:2], "little")
                size = int.from_bytes(body[2:6], "little")
                if size % 16 or 6 + size > len(body):  # a damaged index: walk the chunk
                    pending = (pending[0], None, pending[2])
                elif pending[1] is not None:
                    pairs = np.frombuffer(body[6 : 6 + size], "<u8").reshape(-1, 2)
                    pending[1][channel_id] = pairs
            elif op == OP_MESSAGE:
                _loose_message(body, loose)
            elif op == OP_DATA_END:
                break
            pos = end
        if pending is not None and pos < len(buf):
            done, pending = pending, None
            _gather(done, schemas, channels, loose, skip_topics, problems)
        if pos >= len(buf):  # a cut after a chunk may have left only some of its indexes
            raise _Damage(f"truncated at byte {pos}, before the end of the data")
        if len(buf) < end + FOOTER_SIZE + len(MAGIC) or bytes(buf[-len(MAGIC) :]) != MAGIC:
            raise _Damage("truncated after the data: the summary or footer is missing")
    except _Damage as exc:
        problems.append(f"damaged: {exc}")
        _salvage(pending, schemas, channels, loose)
    except (ValueError, IndexError, KeyError, McapError, struct.error) as exc:
        problems.append(f"damaged: unreadable record ({type(exc).__name__}: {exc})")
        _salvage(pending, schemas, channels, loose)
    for channel_id, (times, datas) in loose.items():
        if channel_id in channels:
            channels[channel_id].pieces.append((np.asarray(times, dtype=np.int64), datas))
    return McapContent(channels, metadata, problems)


def _salvage(pending, schemas, channels, loose) -> None:
    """The messages of a complete chunk whose message indexes the damage cut off."""
    if pending is None:
        return
    with contextlib.suppress(ValueError, IndexError, KeyError, McapError, struct.error):
        _walk_chunk(pending[0], schemas, channels, loose)


def _decompress(body: memoryview) -> bytes:
    """The uncompressed records of a Chunk record body, CRC-checked."""
    uncompressed_size = int.from_bytes(body[16:24], "little")
    crc = int.from_bytes(body[24:28], "little")
    name_len = int.from_bytes(body[28:32], "little")
    compression = bytes(body[32 : 32 + name_len]).decode()
    at = 32 + name_len
    size = int.from_bytes(body[at : at + 8], "little")
    data = body[at + 8 : at + 8 + size]
    try:
        if compression == "zstd":
            raw = zstandard.ZstdDecompressor().decompress(data, max_output_size=uncompressed_size)
        elif compression == "lz4":
            raw = lz4.frame.decompress(bytes(data))
        elif compression == "":
            raw = bytes(data)
        else:
            raise _Damage(f"unknown chunk compression {compression!r}")
    except (zstandard.ZstdError, RuntimeError, OverflowError, MemoryError) as exc:
        raise _Damage(f"chunk cannot be decompressed ({exc})") from None
    if len(raw) != uncompressed_size or (crc and zlib.crc32(raw) != crc):
        raise _Damage("chunk CRC or size mismatch")
    return raw


def _definition(op: int, body, schemas: dict[int, str], channels: dict[int, ChannelData]):
    """Register a Schema or Channel record."""
    if op == OP_SCHEMA:
        s = Schema.read(ReadDataStream(io.BytesIO(body)))
        schemas[s.id] = s.name
    else:
        c = Channel.read(ReadDataStream(io.BytesIO(body)))
        channels[c.id] = ChannelData(c.topic, schemas.get(c.schema_id, ""), c.metadata)


def _gather(
    pending, schemas, channels: dict[int, ChannelData], loose, skip_topics, problems: list[str]
) -> None:
    """Add a chunk's messages to their channels, by its message indexes when it has them.

    A chunk without indexes, or one that defines channels itself (as the official writer
    does), is walked record by record. So is a chunk whose indexes disagree with it: the
    indexes carry no CRC, the chunk does, and every record an index points at must be a
    message of that channel at that time.
    """
    raw, indexes, chunk_at = pending
    if not indexes or any(c not in channels for c in indexes):
        if indexes is None:
            problems.append(
                f"damaged: message index of the chunk at byte {chunk_at}; read without it"
            )
        _walk_chunk(raw, schemas, channels, loose)
        return
    arr = np.frombuffer(raw, dtype=np.uint8)
    found = []
    for channel_id, pairs in indexes.items():
        if not len(pairs) or channels[channel_id].topic in skip_topics:
            continue
        times = pairs[:, 0].astype(np.int64)
        offsets = pairs[:, 1].astype(np.int64)
        lengths = _indexed_lengths(arr, channel_id, times, offsets)
        if lengths is None:
            problems.append(
                f"damaged: message index of the chunk at byte {chunk_at}; read without it"
            )
            _walk_chunk(raw, schemas, channels, loose)
            return
        found.append((channel_id, times, offsets, lengths))
    for channel_id, times, offsets, lengths in found:
        for size in np.unique(lengths):
            mine = lengths == size
            channels[channel_id].pieces.append((times[mine], _payloads(arr, offsets[mine], size)))


def _indexed_lengths(arr: np.ndarray, channel_id: int, times: np.ndarray, offsets: np.ndarray):
    """Payload lengths (n,) of the indexed records, or None unless every one is a whole
    message of `channel_id` at its indexed time."""
    if (offsets < 0).any() or offsets.max() + MESSAGE_HEADER_SIZE > arr.size:
        return None
    lengths = _u64_at(arr, offsets + 1).astype(np.int64) - (MESSAGE_HEADER_SIZE - 9)
    if (lengths < 0).any() or (lengths > arr.size).any():
        return None
    if (offsets + MESSAGE_HEADER_SIZE + lengths > arr.size).any():
        return None
    channel = arr[offsets + 9].astype(np.int64) | (arr[offsets + 10].astype(np.int64) << 8)
    agrees = (
        (arr[offsets] == OP_MESSAGE).all()
        and (channel == channel_id).all()
        and (_u64_at(arr, offsets + 15).astype(np.int64) == times).all()
    )
    return lengths if agrees else None


def _payloads(arr: np.ndarray, offsets: np.ndarray, size: int) -> np.ndarray:
    """Equal-length payloads at record offsets, (n, size) uint8 (a view when evenly spaced)."""
    start = offsets + MESSAGE_HEADER_SIZE
    if start.size > 1:
        stride = int(start[1] - start[0])
        if stride >= size and (np.diff(start) == stride).all():
            base = arr[int(start[0]) :]
            return np.lib.stride_tricks.as_strided(
                base, shape=(start.size, int(size)), strides=(stride, 1), writeable=False
            )
    return arr[start[:, None] + np.arange(size)]


def _u64_at(arr: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    cols = offsets[:, None] + np.arange(8)
    return np.ascontiguousarray(arr[cols]).view("<u8").ravel()


def _walk_chunk(raw: bytes, schemas, channels, loose) -> None:
    """Schemas, channels and messages of a chunk, record by record."""
    pos = 0
    view = memoryview(raw)
    while pos + 9 <= len(raw):
        op = raw[pos]
        length = int.from_bytes(view[pos + 1 : pos + 9], "little")
        body = view[pos + 9 : pos + 9 + length]
        if op == OP_MESSAGE:
            _loose_message(body, loose)
        elif op in (OP_SCHEMA, OP_CHANNEL):
            _definition(op, body, schemas, channels)
        pos += 9 + length


def _loose_message(body: memoryview, loose) -> None:
    channel_id = int.from_bytes(body[0:2], "little")
    log_time = int.from_bytes(body[6:14], "little")
    times, datas = loose[channel_id]
    times.append(log_time)
    datas.append(bytes(body[22:]))
