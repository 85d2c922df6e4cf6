"""Bounded reading: a log's bytes and decompressed chunks never take unbounded time or memory."""

from __future__ import annotations

import os
import sys
import threading
from pathlib import Path

import lz4.frame
import zstandard
from isal.isal_zlib import crc32  # zlib's CRC-32, an order of magnitude faster

from impactlab.files import UnreadableInput, open_regular


class UnreadableFile(ValueError):
    """The path is not a file that can be read as a log (not regular, too large, not MCAP)."""


class DamagedData(Exception):
    """Bytes of a log that cannot be what they claim (a bad chunk, an impossible record)."""


MAX_CHUNK_BYTES = 256 << 20
"""Largest uncompressed size a chunk may declare (impactlab and the official writer: 1 MiB)."""
MAX_LOG_BYTES = 4 << 30
"""Default cap on a file plus its decompressed chunks (a 400,000-step log needs ~0.2 GiB)."""
MAX_LOG_BYTES_ENV = "IMPACTLAB_MAX_LOG_BYTES"


def max_log_bytes() -> int:
    """The cap on a file plus its decompressed chunks, in bytes (`IMPACTLAB_MAX_LOG_BYTES`).

    Raises:
        UnreadableFile: the environment variable is not a positive integer.
    """
    text = os.environ.get(MAX_LOG_BYTES_ENV, "").strip()
    if not text:
        return MAX_LOG_BYTES
    if not text.isdigit() or int(text) <= 0:
        raise UnreadableFile(f"{MAX_LOG_BYTES_ENV} must be a positive number of bytes: {text!r}")
    return int(text)


def read_file(
    path: Path, *, limit: int | None = None, arena: Arena | None = None
) -> bytes | memoryview:
    """The bytes of a regular file of at most `limit` bytes (default `max_log_bytes()`),
    read into `arena` when given and it has room (a read-only view).

    Raises:
        OSError: it cannot be read (FileNotFoundError, IsADirectoryError, ...).
        UnreadableFile: not a regular file, or larger than the limit.
    """
    limit = max_log_bytes() if limit is None else limit
    try:
        stream = open_regular(path)
    except UnreadableInput:
        raise UnreadableFile("not a regular file (a device, pipe or socket): not a log") from None
    with stream:
        size = os.fstat(stream.fileno()).st_size
        if size > limit:
            raise UnreadableFile(f"{_mib(size)} is more than the limit of {_mib(limit)} ({_HINT})")
        room = arena.take(size) if arena is not None and size else None
        if room is None:
            return stream.read(size)  # what the file held when checked (it may still grow)
        got = 0
        while got < size and (n := stream.readinto(room[got:])):
            got += n
        return room[:got].toreadonly()


_HINT = f"raise it with the environment variable {MAX_LOG_BYTES_ENV}"


def _mib(n: int) -> str:
    return f"{n / (1 << 20):.1f} MiB" if n < 1 << 30 else f"{n / (1 << 30):.2f} GiB"


def decompress_chunk(
    body: memoryview, budget: list[int], arena: Arena | None = None
) -> bytes | memoryview:
    """The uncompressed records of a Chunk record body, CRC-checked.

    Never more than the chunk declares (at most `MAX_CHUNK_BYTES`, and within `budget[0]`,
    the bytes the file's decompressed chunks may still take, which it decreases). A zstd
    chunk is decompressed into `arena` when given and it has room (a read-only view).
    """
    uncompressed_size = int.from_bytes(body[16:24], "little")
    crc = int.from_bytes(body[24:28], "little")
    name_len = int.from_bytes(body[28:32], "little")
    compression = bytes(body[32 : 32 + name_len]).decode()
    at = 32 + name_len
    size = int.from_bytes(body[at : at + 8], "little")
    data = body[at + 8 : at + 8 + size]
    if uncompressed_size > MAX_CHUNK_BYTES:
        raise DamagedData(
            f"a chunk declares {_mib(uncompressed_size)} uncompressed, more than the limit of "
            f"{_mib(MAX_CHUNK_BYTES)} per chunk"
        )
    if uncompressed_size > budget[0]:
        raise DamagedData(
            f"the decompressed chunks exceed the limit of {_mib(max_log_bytes())} ({_HINT})"
        )
    budget[0] -= uncompressed_size
    raw: bytes | memoryview
    try:
        if compression == "zstd":
            room = arena.take(uncompressed_size + 1) if arena is not None else None
            if arena is None or room is None:
                raw = _zstd(data, uncompressed_size)
            else:
                raw = arena.zstd(data, room)
        elif compression == "lz4":
            decompressor = lz4.frame.LZ4FrameDecompressor()
            raw = decompressor.decompress(bytes(data), max_length=uncompressed_size + 1)
        elif compression == "":
            raw = bytes(data)
        else:
            raise DamagedData(f"unknown chunk compression {compression!r}")
    except (zstandard.ZstdError, RuntimeError, OverflowError, MemoryError) as exc:
        raise DamagedData(f"chunk cannot be decompressed ({exc})") from None
    if len(raw) != uncompressed_size or (crc and crc32(raw) != crc):
        raise DamagedData("chunk CRC or size mismatch")
    return raw


def _zstd(data: memoryview, declared: int) -> bytes:
    """At most `declared` + 1 bytes of a zstd chunk (one more tells a chunk that lies).

    `ZstdDecompressor.decompress` allocates what the frame header claims, whatever its
    `max_output_size`: it is used only when that claim is the chunk's own (the fast path for
    every well-formed chunk); otherwise the frames are streamed up to the declared size.
    """
    try:
        claimed = zstandard.frame_content_size(data)
    except zstandard.ZstdError:
        claimed = -1
    if claimed == declared and declared > 0:
        return zstandard.ZstdDecompressor().decompress(data, max_output_size=declared)
    reader = zstandard.ZstdDecompressor().stream_reader(data, read_across_frames=True)
    return reader.read(declared + 1) if declared else b""


MAX_ARENA_BYTES = 64 << 20
"""Largest arena kept for the next file (a sweep's logs take a few MiB each)."""


class Arena:
    """Memory for one file's decompressed chunks, kept for the next file read on this thread.

    Fresh memory costs a page fault per 4 KiB page when first written, which for a log of a
    few MiB is a third of the time zstd takes; decompressing into memory written before
    avoids it. The kept buffer is reused only when nothing refers to it any more (no chunk
    of an earlier file is still viewed: its reference count is back to what it was when it
    was made); otherwise a new one is made. Up to `MAX_ARENA_BYTES` is kept; a larger
    file's chunks beyond it get their own memory as usual.
    """

    _kept = threading.local()  # .buffer (bytearray) and .refs (its references when made)

    def __init__(self) -> None:
        kept = self._kept
        free = getattr(kept, "buffer", None) is not None and _refs(kept.buffer) == kept.refs
        self.fresh = not free  # the next take starts a new buffer
        self.used = 0

    def zstd(self, data: memoryview, room: memoryview) -> memoryview:
        """The zstd frames of a chunk decompressed into `room` (its declared size + 1 bytes:
        one more tells a chunk that lies), a read-only view of what they hold. The thread's
        decompressor is reused: its context and window are memory written before too."""
        kept = self._kept
        if getattr(kept, "decompressor", None) is None:
            kept.decompressor = zstandard.ZstdDecompressor()
        reader = kept.decompressor.stream_reader(data, read_across_frames=True)
        got = 0
        while got < len(room) and (n := reader.readinto(room[got:])):
            got += n
        return room[:got].toreadonly()

    def take(self, size: int) -> memoryview | None:
        """`size` bytes of the arena not handed out yet, or None (no room within the cap)."""
        kept = self._kept
        if self.fresh or self.used + size > len(kept.buffer):
            grown = 2 * len(kept.buffer) if getattr(kept, "buffer", None) is not None else 0
            length = min(max(grown, 4 << 20, size), MAX_ARENA_BYTES)
            if size > length:
                return None
            kept.buffer = bytearray(length)
            kept.refs = _refs(kept.buffer)
            self.fresh, self.used = False, 0
        view = memoryview(kept.buffer)[self.used : self.used + size]
        self.used += size
        return view


def _refs(obj: object) -> int:
    return sys.getrefcount(obj)
