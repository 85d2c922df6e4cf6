"""Read an MCAP file within bounds: each channel's complete messages as arrays, its metadata and
attachments, and what is damaged (the walk stops there; everything before it is kept)."""

from __future__ import annotations

import contextlib
import io
import os
import struct
import threading
from collections import defaultdict
from dataclasses import dataclass, field
from itertools import compress
from pathlib import Path

import lz4.frame
import numpy as np
import zstandard
from isal.isal_zlib import crc32  # zlib's CRC-32, an order of magnitude faster
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Header, Metadata, Schema

from impactlab.files import UnreadableInput, open_regular
from impactlab.logs.inputs import MAGIC

OP_MESSAGE, OP_INDEX, OP_CHUNK = int(Opcode.MESSAGE), int(Opcode.MESSAGE_INDEX), int(Opcode.CHUNK)
FOOTER_SIZE = 1 + 8 + 8 + 8 + 4  # opcode, length, summary start, summary offset start, CRC
HEAD = 1 + 8 + 2 + 4 + 8 + 8  # a message record: opcode, length, channel, sequence, two times
HEADER = np.dtype(
    {
        "names": ["op", "length", "channel", "log_time"],
        "itemsize": HEAD,
        "formats": ["u1", "<u8", "<u2", "<u8"],
        "offsets": [0, 1, 9, 15],
    }
)
UNREADABLE = (ValueError, IndexError, KeyError, McapError, struct.error)  # a record's bytes
MAX_TIME_NS = (1 << 63) - 1  # the largest log_time the frames' signed nanoseconds hold
MAX_CHUNK_BYTES = 256 << 20
"""Largest uncompressed size a chunk may declare (impactlab and the official writer: 1 MiB)."""
MAX_LOG_BYTES = 4 << 30
"""Default cap on a file plus its decompressed chunks (a 400,000-step log needs ~0.2 GiB)."""
MAX_LOG_BYTES_ENV = "IMPACTLAB_MAX_LOG_BYTES"
_HINT = f"raise it with the environment variable {MAX_LOG_BYTES_ENV}"


class UnreadableFile(ValueError):
    """The path is not a file that can be read as a log (not regular, too large, not MCAP)."""


class DamagedData(Exception):
    """Bytes of a log that cannot be what they claim (a bad chunk, an impossible record)."""


@dataclass
class ChannelData:
    """One channel's messages in pieces of (times (n,) int64 ns, payloads): (n, L) uint8 when
    they have one length, else a list of bytes."""

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
    """What a walk found: channels, metadata records, attachments (data, CRC-checked), damage."""

    channels: dict[int, ChannelData]
    metadata: dict[str, dict[str, str]]
    problems: list[str]
    attachments: dict[str, memoryview] = field(default_factory=dict)  # views of the file
    conflicts: dict[str, dict[str, str]] = field(default_factory=dict)  # per record, per key:
    # the problem of a key that records of one name hold with different values (the first kept)
    summary: bool = False  # the footer points at a summary section
    library: str = ""  # the writer, as its header says


def max_log_bytes() -> int:
    """The cap on a file plus its decompressed chunks, bytes; UnreadableFile when the
    environment variable `IMPACTLAB_MAX_LOG_BYTES` is not a positive integer."""
    text = os.environ.get(MAX_LOG_BYTES_ENV, "").strip()
    if not text:
        return MAX_LOG_BYTES
    if not text.isdigit() or int(text) <= 0:
        raise UnreadableFile(f"{MAX_LOG_BYTES_ENV} must be a positive number of bytes: {text!r}")
    return int(text)


def read_file(path: Path, limit: int) -> bytes:
    """The bytes of a regular file (`files.open_regular`: a device, pipe or socket might
    never end), UnreadableFile beyond `limit` bytes."""
    try:
        stream = open_regular(path)
    except UnreadableInput:
        raise UnreadableFile("not a regular file (a device, pipe or socket): not a log") from None
    with stream:
        size = os.fstat(stream.fileno()).st_size
        if size > limit:
            raise UnreadableFile(f"{_mib(size)} is more than the limit of {_mib(limit)} ({_HINT})")
        return stream.read(size)


def _mib(n: int) -> str:
    return f"{n / (1 << 20):.1f} MiB" if n < 1 << 30 else f"{n / (1 << 30):.2f} GiB"


def read_mcap(
    path: Path, *, skip_topics: frozenset[str] = frozenset(), messages: bool = True
) -> McapContent:
    """Every complete message, metadata record and attachment of an MCAP file, and what is
    damaged. Messages on `skip_topics` are not gathered; without `messages`, no chunk is
    decompressed. A chunk's message indexes give each channel's records, checked against the
    chunk (they carry no CRC, the chunk does); a chunk without them, or one they disagree
    with, is walked record by record. OSError when the file cannot be read, UnreadableFile
    when it is not regular, larger than the limit, or not MCAP."""
    limit = max_log_bytes()
    buf = memoryview(read_file(Path(path), limit))
    if bytes(buf[:8]) != MAGIC:
        raise UnreadableFile("not an MCAP file (bad magic bytes)")
    walk = _Walk(skip_topics, limit - len(buf))
    content = McapContent(walk.channels, {}, walk.problems)
    pos = end = 8
    pending: tuple[memoryview, dict[int, np.ndarray] | None, int] | None = None
    try:
        while pos < len(buf):
            if pos + 9 > len(buf):
                raise DamagedData(f"truncated at byte {pos}")
            op, length = buf[pos], int.from_bytes(buf[pos + 1 : pos + 9], "little")
            end = pos + 9 + length
            if end > len(buf):
                raise DamagedData(f"truncated inside a record at byte {pos}")
            if op == 0:
                raise DamagedData(f"invalid record (opcode 0) at byte {pos}")
            body = buf[pos + 9 : end]
            if op != OP_INDEX and pending is not None:
                walk.chunk(*pending)
                pending = None
            if op in (Opcode.SCHEMA, Opcode.CHANNEL, OP_MESSAGE):
                walk.record(op, body)
            elif op == Opcode.METADATA:
                m = Metadata.read(ReadDataStream(io.BytesIO(body)))
                add_metadata(content.metadata, content.conflicts, m.name, dict(m.metadata))
            elif op == Opcode.HEADER:
                content.library = Header.read(ReadDataStream(io.BytesIO(body))).library
            elif op == Opcode.ATTACHMENT:
                name, data = _attachment(body)
                if data is None:
                    walk.problems.append(f"damaged: attachment {name!r} (CRC or size mismatch)")
                else:
                    content.attachments[name] = data
            elif op == OP_CHUNK and messages:
                pending = (walk.decompress(body), {}, pos)
            elif op == OP_INDEX and pending is not None and pending[1] is not None:
                size = int.from_bytes(body[2:6], "little")
                if size % 16 or 6 + size > len(body):  # a damaged index: walk the chunk
                    pending = (pending[0], None, pending[2])
                else:
                    pairs = np.frombuffer(body[6 : 6 + size], "<u8").reshape(-1, 2)
                    pending[1][int.from_bytes(body[0:2], "little")] = pairs  # type: ignore[index]
            elif op == Opcode.DATA_END:
                break
            pos = end
        if pending is not None and pos < len(buf):
            walk.chunk(*pending)
            pending = None
        if pos >= len(buf):  # a cut after a chunk may have left only some of its indexes
            raise DamagedData(f"truncated at byte {pos}, before the end of the data")
        footer = len(buf) - FOOTER_SIZE - len(MAGIC)
        if footer < end or bytes(buf[-len(MAGIC) :]) != MAGIC:
            raise DamagedData("truncated after the data: the summary or footer is missing")
        content.summary = buf[footer] == Opcode.FOOTER and any(buf[footer + 9 : footer + 17])
    except DamagedData as exc:
        walk.problems.append(f"damaged: {exc}")
        walk.salvage(pending)
    except UNREADABLE as exc:
        walk.problems.append(f"damaged: unreadable record ({type(exc).__name__}: {exc})")
        walk.salvage(pending)
    walk.finish()
    return content


def add_metadata(
    metadata: dict[str, dict[str, str]],
    conflicts: dict[str, dict[str, str]],
    name: str,
    record: dict[str, str],
) -> None:
    """Keep a metadata record; of a second record of the same name, each key it gives
    differently from the first (or that one of them lacks) is a conflict, the first kept."""
    first = metadata.setdefault(name, record)
    if first is record:
        return
    for key in sorted(first.keys() | record.keys()):
        if first.get(key) != record.get(key):
            conflicts.setdefault(name, {})[key] = (
                f"two {name} records disagree ({first.get(key)!r}, then {record.get(key)!r})"
            )


def read_attachments(path: Path) -> dict[str, bytes]:
    """Every complete, CRC-checked attachment of an MCAP file by name ({} when it cannot be
    read; chunks are not decompressed)."""
    try:
        found = read_mcap(Path(path), messages=False).attachments
    except (OSError, ValueError):
        return {}
    return {name: bytes(data) for name, data in found.items()}


def _attachment(body: memoryview) -> tuple[str, memoryview | None]:
    """Name and data of an Attachment record body (None: cut short, or a CRC mismatch)."""
    at = 16 + 4 + int.from_bytes(body[16:20], "little")  # log time, create time, name
    name = bytes(body[20:at]).decode()
    at += 4 + int.from_bytes(body[at : at + 4], "little")  # media type
    size = int.from_bytes(body[at : at + 8], "little")
    crc = int.from_bytes(body[at + 8 + size : at + 12 + size], "little")
    if at + 8 + size + 4 > len(body) or (crc and crc32(body[: at + 8 + size]) != crc):
        return name, None
    return name, body[at + 8 : at + 8 + size]


class _Walk:
    """The channels and messages found so far."""

    def __init__(self, skip_topics: frozenset[str], budget: int) -> None:
        self.skip = skip_topics
        self.budget = budget  # bytes the decompressed chunks may still take
        self.schemas: dict[int, str] = {}
        self.channels: dict[int, ChannelData] = {}
        self.problems: list[str] = []
        self.loose: dict[int, tuple[list[int], list[bytes]]] = defaultdict(lambda: ([], []))

    def record(self, op: int, body: memoryview) -> None:
        """A Schema, Channel or Message record (in a chunk or not)."""
        if op == OP_MESSAGE:
            if len(body) < HEAD - 9:
                raise DamagedData("message record cut short")
            times, payloads = self.loose[int.from_bytes(body[0:2], "little")]
            times.append(int.from_bytes(body[6:14], "little"))
            payloads.append(bytes(body[22:]))
        elif op == Opcode.SCHEMA:
            schema = Schema.read(ReadDataStream(io.BytesIO(body)))
            self.schemas[schema.id] = schema.name
        else:
            c = Channel.read(ReadDataStream(io.BytesIO(body)))
            self.channels[c.id] = ChannelData(
                c.topic, self.schemas.get(c.schema_id, ""), c.metadata
            )

    def decompress(self, body: memoryview) -> memoryview:
        """The uncompressed records of a Chunk record body, CRC-checked, never more than it
        declares (at most `MAX_CHUNK_BYTES`, and within the file's budget)."""
        size = int.from_bytes(body[16:24], "little")
        crc = int.from_bytes(body[24:28], "little")
        at = 32 + int.from_bytes(body[28:32], "little")
        compression = bytes(body[32:at]).decode()
        data = body[at + 8 : at + 8 + int.from_bytes(body[at : at + 8], "little")]
        if size > MAX_CHUNK_BYTES:
            raise DamagedData(
                f"a chunk declares {_mib(size)} uncompressed, more than the limit of "
                f"{_mib(MAX_CHUNK_BYTES)} per chunk"
            )
        if size > self.budget:
            raise DamagedData(
                f"the decompressed chunks exceed the limit of {_mib(max_log_bytes())} ({_HINT})"
            )
        self.budget -= size
        raw: bytes | memoryview
        try:
            if compression == "zstd":  # never more than declared, whatever the frame claims
                reader = zstandard.ZstdDecompressor().stream_reader(data, read_across_frames=True)
                room, got = _scratch(size + 1), 0  # one byte more tells a chunk that lies
                while got < len(room) and (n := reader.readinto(room[got:])):
                    got += n
                raw = room[:got]
            elif compression == "lz4":
                raw = lz4.frame.LZ4FrameDecompressor().decompress(bytes(data), max_length=size + 1)
            elif compression == "":
                raw = bytes(data)
            else:
                raise DamagedData(f"unknown chunk compression {compression!r}")
        except (zstandard.ZstdError, RuntimeError, OverflowError, MemoryError) as exc:
            raise DamagedData(f"chunk cannot be decompressed ({exc})") from None
        if len(raw) != size or (crc and crc32(raw) != crc):
            raise DamagedData("chunk CRC or size mismatch")
        return memoryview(raw).toreadonly()

    def chunk(self, raw: memoryview, indexes: dict[int, np.ndarray] | None, at: int) -> None:
        """Add a chunk's messages, by its message indexes when they agree with it."""
        found = []
        damaged = f"damaged: message index of the chunk at byte {at}; read without it"
        for channel_id, pairs in (indexes or {}).items():
            channel = self.channels.get(channel_id)
            if channel is None:  # a chunk that defines its own channels (the official writer)
                break
            if not len(pairs) or channel.topic in self.skip:
                continue
            if (piece := _indexed(raw, channel_id, pairs)) is None:
                self.problems.append(damaged)
                break
            found.append((channel, piece))
        else:
            for channel, piece in found:
                channel.pieces.append(piece)
            if indexes:
                return
            if indexes is None:
                self.problems.append(damaged)
        self.walk(raw)

    def walk(self, raw: memoryview) -> None:
        """A chunk's records one by one; DamagedData for a record it cannot hold."""
        pos = 0
        while pos < len(raw):
            op, length = raw[pos], int.from_bytes(raw[pos + 1 : pos + 9], "little")
            if op not in (Opcode.SCHEMA, Opcode.CHANNEL, OP_MESSAGE) or pos + 9 + length > len(raw):
                raise DamagedData(f"invalid record (opcode {op}) inside a chunk")
            self.record(op, raw[pos + 9 : pos + 9 + length])
            pos += 9 + length

    def salvage(self, pending: tuple[memoryview, object, int] | None) -> None:
        """The messages of a complete chunk whose message indexes the damage cut off."""
        if pending is not None:
            with contextlib.suppress(DamagedData, *UNREADABLE):
                self.walk(pending[0])

    def finish(self) -> None:
        """Loose messages into their channels; times as int64 ns (messages at log_time >=
        2^63 ns are skipped and reported)."""
        for channel_id, (times, payloads) in self.loose.items():
            if channel_id in self.channels:
                self.channels[channel_id].pieces.append((np.array(times, np.uint64), payloads))
        dropped: dict[str, int] = {}
        for c in self.channels.values():
            kept = []
            for t, data in c.pieces:
                ok = t <= MAX_TIME_NS
                if not ok.all():
                    dropped[c.topic] = dropped.get(c.topic, 0) + int((~ok).sum())
                    t = t[ok]
                    data = data[ok] if isinstance(data, np.ndarray) else list(compress(data, ok))
                if len(t):
                    kept.append((t.astype(np.int64), data))
            c.pieces = kept
        if dropped:
            self.problems.append(
                f"damaged: {sum(dropped.values())} message(s) at log_time >= 2^63 ns (beyond 292 "
                f"years) skipped, on {', '.join(dropped)}"
            )


_SCRATCH = threading.local()
MAX_SCRATCH_BYTES = 64 << 20  # a larger chunk gets memory of its own


def _scratch(size: int) -> memoryview:
    """This thread's memory for one decompressed chunk, reused for the next (fresh memory
    costs a page fault per 4 KiB): nothing read keeps a view of a chunk, every message is
    copied out of it before the next chunk is decompressed (`_indexed`, `_Walk.record`)."""
    if size > MAX_SCRATCH_BYTES:
        return memoryview(bytearray(size))
    if len(getattr(_SCRATCH, "buffer", b"")) < size:
        _SCRATCH.buffer = bytearray(max(size, 1 << 20))
    return memoryview(_SCRATCH.buffer)[:size]


def _indexed(
    raw: memoryview, channel_id: int, pairs: np.ndarray
) -> tuple[np.ndarray, np.ndarray | list[bytes]] | None:
    """One channel's messages in a chunk by its index: (times, payloads), or None unless every
    entry points at a whole message of that channel at its indexed time."""
    offsets = pairs[:, 1].astype(np.int64)  # an offset >= 2^63 reads as negative
    if offsets.min() < 0 or offsets.max() + HEAD > len(raw):
        return None
    head = _take(raw, offsets, HEAD).view(HEADER)[:, 0]
    lengths = head["length"].astype(np.int64) - (HEAD - 9)
    if lengths.min() < 0 or (offsets + lengths).max() + HEAD > len(raw):
        return None
    if not (
        (head["op"] == OP_MESSAGE).all()
        and (head["channel"] == channel_id).all()
        and (head["log_time"] == pairs[:, 0]).all()
    ):
        return None
    starts = offsets + HEAD
    if (lengths == lengths[0]).all():
        return pairs[:, 0], _take(raw, starts, int(lengths[0]))
    ends = (starts + lengths).tolist()
    return pairs[:, 0], [bytes(raw[s:e]) for s, e in zip(starts.tolist(), ends, strict=True)]


def _take(raw: memoryview, starts: np.ndarray, size: int) -> np.ndarray:
    """The `size` bytes at each offset of `raw`, (n, size) uint8 (one gather)."""
    if size == 0:
        return np.empty((len(starts), 0), np.uint8)
    rows = np.ndarray((len(raw) - size + 1,), np.dtype((np.void, size)), raw, strides=(1,))
    taken: np.ndarray = rows[starts].view(np.uint8).reshape(-1, size)
    return taken
