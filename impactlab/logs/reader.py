"""Walk an MCAP file's records and gather each channel's messages as arrays.

Top-level records are read one by one (a handful per file: header, schemas, channels,
metadata, chunks and their message indexes). Inside a chunk, the message indexes that
follow it give every message's offset, so a channel's messages are checked and taken as
whole arrays (`chunk_index`: views into the chunk where they are evenly spaced) instead of
one Python step per message; a chunk without indexes, or whose
indexes disagree with it (they carry no CRC), is walked record by record. Damage (truncation,
a bad CRC, an undecompressable chunk, an unreadable record) stops the walk: everything
complete before it is returned, with the problem.

Reads are bounded (`bounded`): only regular files, at most `max_log_bytes()` for the file and
its decompressed chunks together, never more decompressed than a chunk declares. Message
times are unsigned 64-bit in MCAP; the frames hold signed 64-bit nanoseconds, so a message at
log_time >= 2^63 ns (292 years) is skipped and reported.
"""

from __future__ import annotations

import contextlib
import functools
import io
import struct
from collections import defaultdict
from dataclasses import dataclass, field
from itertools import compress
from pathlib import Path

import numpy as np
from isal.isal_zlib import crc32
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Header, Metadata, Schema

from impactlab.logs.bounded import (
    Arena,
    DamagedData,
    UnreadableFile,
    decompress_chunk,
    max_log_bytes,
    read_file,
)
from impactlab.logs.chunk_index import MESSAGE_HEADER_SIZE, OP_MESSAGE, add_pieces, checked_index
from impactlab.logs.file_index import Chunk, gather_indexed

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER = int(Opcode.HEADER), int(Opcode.FOOTER)
OP_SCHEMA, OP_CHANNEL, OP_CHUNK = int(Opcode.SCHEMA), int(Opcode.CHANNEL), int(Opcode.CHUNK)
OP_MESSAGE_INDEX = int(Opcode.MESSAGE_INDEX)
OP_ATTACHMENT, OP_METADATA = int(Opcode.ATTACHMENT), int(Opcode.METADATA)
OP_DATA_END = int(Opcode.DATA_END)
CHUNK_OPS = frozenset({OP_SCHEMA, OP_CHANNEL, OP_MESSAGE})  # what a chunk may hold
FOOTER_SIZE = 1 + 8 + 8 + 8 + 4  # opcode, length, summary start, summary offset start, CRC
MAX_TIME_NS = (1 << 63) - 1  # the largest log_time the frames' signed nanoseconds hold


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
    attachments: dict[str, int] = field(default_factory=dict)  # name -> size in bytes
    summary: bool = False  # the footer points at a summary section
    library: str = ""  # the writer, as its header says


_Damage = DamagedData
_Chunk = bytes | memoryview  # a chunk's uncompressed records
_Pending = tuple[_Chunk, dict[int, np.ndarray] | None, int]  # records, indexes, byte offset
_Loose = dict[int, tuple[list[int], list[bytes]]]  # messages outside indexes, by channel


def read_mcap(
    path: Path, *, skip_topics: frozenset[str] = frozenset(), reuse_memory: bool = False
) -> McapContent:
    """Gather every complete message and metadata record of an MCAP file.

    Messages on `skip_topics` are not gathered (their channels are still listed). With
    `reuse_memory`, chunks are decompressed into this thread's `Arena`, memory the previous
    such read used when nothing refers to it any more (for a caller that decodes the
    content and drops it before reading the next file).

    The indexed chunks are checked together at the end, channel by channel (`file_index`);
    a file with any problem is read again chunk by chunk, which says what is wrong.

    Raises:
        UnreadableFile: not a regular file, larger than the limit, or not MCAP (bad magic).
        OSError: the file cannot be read.
    """
    content = _read(Path(path), skip_topics, reuse_memory, together=True)
    if content is None:  # a problem: read again chunk by chunk, which says what is wrong
        content = _read(Path(path), skip_topics, reuse_memory)
        assert content is not None  # only a `together` read gives up
    return content


def _read(
    path: Path, skip_topics: frozenset[str], reuse_memory: bool, together: bool = False
) -> McapContent | None:
    """`read_mcap`; `together`: the indexed chunks checked at the end, None on any problem."""
    limit = max_log_bytes()
    arena = Arena() if reuse_memory else None
    buf = memoryview(read_file(Path(path), limit=limit, arena=arena))
    if bytes(buf[:8]) != MAGIC:
        raise UnreadableFile("not an MCAP file (bad magic bytes)")
    budget = [limit - len(buf)]  # bytes the decompressed chunks may still take
    schemas: dict[int, str] = {}
    channels: dict[int, ChannelData] = {}
    metadata: dict[str, dict[str, str]] = {}
    attachments: dict[str, int] = {}
    library = ""
    problems: list[str] = []
    loose: _Loose = defaultdict(lambda: ([], []))
    pos = 8
    pending: _Pending | None = None
    deferred: list[Chunk] | None = [] if together else None  # indexed chunks, checked at the end
    try:
        while pos < len(buf):
            if pos + 9 > len(buf):
                raise _Damage(f"truncated at byte {pos}")
            op = buf[pos]
            length = int.from_bytes(buf[pos + 1 : pos + 9], "little")
            end = pos + 9 + length
            if end > len(buf):
                raise _Damage(f"truncated inside a record at byte {pos}")
            if op == 0:
                raise _Damage(f"invalid record (opcode 0) at byte {pos}")
            body = buf[pos + 9 : end]
            if op != OP_MESSAGE_INDEX and pending is not None:
                done, pending = pending, None
                _gather(done, schemas, channels, loose, skip_topics, problems, deferred)
            if op in (OP_SCHEMA, OP_CHANNEL):
                _definition(op, body, schemas, channels)
            elif op == OP_METADATA:
                m = Metadata.read(ReadDataStream(io.BytesIO(body)))
                metadata[m.name] = dict(m.metadata)
            elif op == OP_HEADER:
                library = Header.read(ReadDataStream(io.BytesIO(body))).library
            elif op == OP_ATTACHMENT:
                name, _, size = _attachment_header(body)
                attachments[name] = size
            elif op == OP_CHUNK:
                pending = (decompress_chunk(body, budget, arena), {}, pos)
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
            _gather(done, schemas, channels, loose, skip_topics, problems, deferred)
        if pos >= len(buf):  # a cut after a chunk may have left only some of its indexes
            raise _Damage(f"truncated at byte {pos}, before the end of the data")
        footer_at = len(buf) - FOOTER_SIZE - len(MAGIC)
        if footer_at < end or bytes(buf[-len(MAGIC) :]) != MAGIC:
            raise _Damage("truncated after the data: the summary or footer is missing")
        summary = (
            buf[footer_at] == OP_FOOTER
            and int.from_bytes(buf[footer_at + 9 : footer_at + 17], "little") != 0
        )
    except _Damage as exc:
        problems.append(f"damaged: {exc}")
        _salvage(pending, schemas, channels, loose)
        summary = False
    except (ValueError, IndexError, KeyError, McapError, struct.error) as exc:
        problems.append(f"damaged: unreadable record ({type(exc).__name__}: {exc})")
        _salvage(pending, schemas, channels, loose)
        summary = False
    if deferred is not None and (
        problems or not gather_indexed(deferred, channels, skip_topics, arena)
    ):
        return None
    for channel_id, (times, datas) in loose.items():
        if channel_id in channels:
            channels[channel_id].pieces.append((np.asarray(times, dtype=np.uint64), datas))
    _signed_times(channels, problems)
    return McapContent(channels, metadata, problems, attachments, summary, library)


def _signed_times(channels: dict[int, ChannelData], problems: list[str]) -> None:
    """Message times as int64 ns; messages at log_time >= 2^63 are dropped and reported."""
    dropped: dict[str, int] = {}
    for channel in channels.values():
        kept = []
        for t, data in channel.pieces:
            ok = t <= MAX_TIME_NS
            if not ok.all():
                dropped[channel.topic] = dropped.get(channel.topic, 0) + int((~ok).sum())
                t = t[ok]
                data = data[ok] if isinstance(data, np.ndarray) else list(compress(data, ok))
            if len(t):
                kept.append((t.astype(np.int64), data))
        channel.pieces = kept
    if dropped:
        problems.append(
            f"damaged: {sum(dropped.values())} message(s) at log_time >= 2^63 ns (beyond 292 "
            f"years) skipped, on {', '.join(dropped)}"
        )


def _salvage(
    pending: _Pending | None,
    schemas: dict[int, str],
    channels: dict[int, ChannelData],
    loose: _Loose,
) -> None:
    """The messages of a complete chunk whose message indexes the damage cut off."""
    if pending is None:
        return
    with contextlib.suppress(_Damage, ValueError, IndexError, KeyError, McapError, struct.error):
        _walk_chunk(pending[0], schemas, channels, loose)


def read_attachments(path: Path) -> dict[str, bytes]:
    """Every complete, CRC-checked attachment of an MCAP file, by name (chunks are skipped, not
    decompressed; damage, or a file that cannot be read, ends the walk)."""
    try:
        buf = memoryview(read_file(Path(path)))
    except (OSError, ValueError):
        return {}
    out: dict[str, bytes] = {}
    pos = len(MAGIC) if bytes(buf[: len(MAGIC)]) == MAGIC else len(buf)
    while pos + 9 <= len(buf):
        op = buf[pos]
        end = pos + 9 + int.from_bytes(buf[pos + 1 : pos + 9], "little")
        if op in (0, OP_DATA_END) or end > len(buf):
            break
        if op == OP_ATTACHMENT:
            body = buf[pos + 9 : end]
            try:
                name, data_at, size = _attachment_header(body)
            except (DamagedData, UnicodeDecodeError):
                break
            crc = int.from_bytes(body[data_at + size : data_at + size + 4], "little")
            if crc and crc32(body[: data_at + size]) != crc:
                break
            out[name] = bytes(body[data_at : data_at + size])
        pos = end
    return out


def _attachment_header(body: memoryview) -> tuple[str, int, int]:
    """Name, data offset and data size of an Attachment record body (the data not copied).

    Raises:
        DamagedData: the record is cut short.
    """
    at = 16  # log time, create time
    name_len = int.from_bytes(body[at : at + 4], "little")
    name = bytes(body[at + 4 : at + 4 + name_len]).decode()
    at += 4 + name_len
    at += 4 + int.from_bytes(body[at : at + 4], "little")  # media type
    size = int.from_bytes(body[at : at + 8], "little")
    if at + 8 + size + 4 > len(body):
        raise DamagedData("attachment record cut short")
    return name, at + 8, size


def _definition(
    op: int, body: memoryview, schemas: dict[int, str], channels: dict[int, ChannelData]
) -> None:
    """Register a Schema or Channel record."""
    small = len(body) <= MAX_CACHED_RECORD  # the logs of a sweep repeat the same records
    if op == OP_SCHEMA:
        schema_id, name = (_schema if small else _schema.__wrapped__)(bytes(body))
        schemas[schema_id] = name
    else:
        parsed = (_channel if small else _channel.__wrapped__)(bytes(body))
        channel_id, schema_id, topic, metadata = parsed
        channels[channel_id] = ChannelData(topic, schemas.get(schema_id, ""), dict(metadata))


MAX_CACHED_RECORD = 64 << 10  # larger Schema and Channel records are parsed each time


@functools.lru_cache(maxsize=256)
def _schema(body: bytes) -> tuple[int, str]:
    """Id and name of a Schema record."""
    s = Schema.read(ReadDataStream(io.BytesIO(body)))
    return s.id, s.name


@functools.lru_cache(maxsize=256)
def _channel(body: bytes) -> tuple[int, int, str, tuple[tuple[str, str], ...]]:
    """Id, schema id, topic and metadata of a Channel record."""
    c = Channel.read(ReadDataStream(io.BytesIO(body)))
    return c.id, c.schema_id, c.topic, tuple(c.metadata.items())


def _gather(
    pending: _Pending,
    schemas: dict[int, str],
    channels: dict[int, ChannelData],
    loose: _Loose,
    skip_topics: frozenset[str],
    problems: list[str],
    deferred: list[Chunk] | None = None,
) -> None:
    """Add a chunk's messages to their channels, by its message indexes when it has them.

    A chunk without indexes, or one that defines channels itself (as the official writer
    does), is walked record by record. So is a chunk whose indexes disagree with it: the
    indexes carry no CRC, the chunk does, and every record an index points at must be a
    message of that channel at that time. The indexed messages are checked together; each
    channel's payloads are added as views into the chunk where they are evenly spaced.
    """
    raw, indexes, chunk_at = pending
    if not indexes or any(c not in channels for c in indexes):
        if indexes is None:
            problems.append(
                f"damaged: message index of the chunk at byte {chunk_at}; read without it"
            )
        _walk_chunk(raw, schemas, channels, loose)
        return
    if deferred is not None:  # checked with the file's other chunks (`file_index`)
        deferred.append((raw, indexes))
        return
    found = []
    for channel_id, pairs in indexes.items():
        if not len(pairs) or channels[channel_id].topic in skip_topics:
            continue
        checked = checked_index(raw, channel_id, pairs)
        if checked is None:
            problems.append(
                f"damaged: message index of the chunk at byte {chunk_at}; read without it"
            )
            _walk_chunk(raw, schemas, channels, loose)
            return
        found.append((channels[channel_id], pairs[:, 0], *checked))
    for channel, times, offsets, lengths, step in found:
        add_pieces(channel.pieces, raw, times, offsets + MESSAGE_HEADER_SIZE, lengths, step)


def _walk_chunk(
    raw: _Chunk, schemas: dict[int, str], channels: dict[int, ChannelData], loose: _Loose
) -> None:
    """Schemas, channels and messages of a chunk, record by record.

    Raises:
        _Damage: a record that a chunk cannot hold, or one that overruns the chunk.
    """
    pos = 0
    view = memoryview(raw)
    while pos < len(raw):
        op = raw[pos]
        length = int.from_bytes(view[pos + 1 : pos + 9], "little")
        if op not in CHUNK_OPS or pos + 9 + length > len(raw):
            raise _Damage(f"invalid record (opcode {op}) inside a chunk")
        body = view[pos + 9 : pos + 9 + length]
        if op == OP_MESSAGE:
            _loose_message(body, loose)
        else:
            _definition(op, body, schemas, channels)
        pos += 9 + length


def _loose_message(body: memoryview, loose: _Loose) -> None:
    if len(body) < MESSAGE_HEADER_SIZE - 9:
        raise _Damage("message record cut short")
    channel_id = int.from_bytes(body[0:2], "little")
    log_time = int.from_bytes(body[6:14], "little")
    times, datas = loose[channel_id]
    times.append(log_time)
    datas.append(bytes(body[22:]))
