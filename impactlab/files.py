"""Files read and written safely: inputs read only as bounded regular files, outputs renamed
into place once complete, output folders checked before any work."""

from __future__ import annotations

import contextlib
import errno
import io
import itertools
import json
import math
import os
import re
import secrets
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from impactlab.errors import ImpactlabError

NAME_MAX = 255  # bytes of one file name (Linux, macOS)
DEEPEST_BYTES = 300  # below an output folder at most: a staging folder, figures/, a name
FULL_BELOW_BYTES = 1 << 20  # a disk with less free is full for a write that failed on it
FULL = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)  # a full disk or quota, a file size limit
NOT_TEXT = "the path is not UTF-8 text, which tables, reports and logs hold: rename it"


class OutputError(ImpactlabError):
    """An output folder or file cannot be created or written. Exit code 2."""

    exit_code = 2

    def __init__(self, path: Path | str, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")


class UnreadableInput(OSError):
    """Not an input impactlab reads: not a regular file, or larger than its limit."""

    def __str__(self) -> str:
        return str(self.strerror)


def is_text(path: str | os.PathLike[str]) -> bool:
    """Whether a path is UTF-8 text (Python holds its other bytes as lone surrogates)."""
    return re.search("[\udc80-\udcff]", os.fspath(path)) is None


def open_regular(path: str | os.PathLike[str]) -> io.BufferedReader:
    """`path` opened for reading (the caller closes it) when it is a regular file (links
    followed), without ever waiting: a FIFO is opened non-blocking and then refused, as are
    devices and sockets.

    Raises:
        OSError: it cannot be opened (FileNotFoundError, IsADirectoryError, ...);
            `UnreadableInput`: not a regular file.
    """
    _check_regular(os.stat(path).st_mode, path)  # before opening: a socket cannot be opened
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    stream = open(fd, "rb")  # noqa: SIM115 (the caller's to close)
    try:
        _check_regular(os.fstat(fd).st_mode, path)  # and what was opened, as it may differ
    except OSError:
        stream.close()
        raise
    return stream


def _check_regular(mode: int, path: str | os.PathLike[str]) -> None:
    if stat.S_ISDIR(mode):
        raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), os.fspath(path))
    if not stat.S_ISREG(mode):
        raise UnreadableInput(errno.EINVAL, "not a regular file (a device, pipe or socket)")


def read_regular(path: str | os.PathLike[str], limit: int) -> bytes:
    """The bytes of `path`, a regular file (`open_regular`) of at most `limit` bytes; never
    more than `limit` + 1 bytes are read, whatever the file claims or becomes.

    Raises:
        OSError: it cannot be read; `UnreadableInput`: not a regular file, or too large.
    """
    with open_regular(path) as stream:
        data = stream.read(limit + 1)
    if len(data) > limit:
        raise UnreadableInput(errno.EFBIG, f"larger than {limit:,} bytes")
    return data


def check_writable(out_dir: Path) -> None:
    """Create the output folder and prove a file can be written in it, before any work.

    Raises:
        OutputError: it cannot, or its path leaves too little room under the system's limit
            (PATH_MAX) for the files impactlab writes in it (`DEEPEST_BYTES`).
    """
    longest = os.pathconf("/", "PC_PATH_MAX") - 1 - DEEPEST_BYTES
    length = len(os.fsencode(os.path.abspath(out_dir)))
    if length > longest:
        raise OutputError(
            out_dir,
            f"the path is too long: {length:,} bytes (absolute), at most {longest:,}: the "
            f"system's limit less {DEEPEST_BYTES} bytes for the files written in it",
        )
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out_dir, prefix=".impactlab-write-test-"):
            pass
    except OSError as exc:
        raise OutputError(out_dir, f"cannot write there: {exc.strerror or exc}") from None


@contextlib.contextmanager
def full_disk_error(out: Path) -> Iterator[None]:
    """Turn a full disk (`FULL`) while writing into `out` into `OutputError`: one line, exit
    code 2, where nothing more of the job can be written."""
    try:
        yield
    except OSError as exc:
        if exc.errno not in FULL:
            raise
        raise OutputError(out, f"cannot write: {os.strerror(exc.errno)}") from None


def temporary_path(path: Path) -> Path:
    """A name `path` can be written under until it is complete: hidden, beside it, unique
    (random: to this call, whatever the process or thread), its name cut (by characters)
    to fit NAME_MAX bytes."""
    name, suffix = path.name, f".{secrets.token_hex(4)}.tmp"
    while len(os.fsencode(f".{name}{suffix}")) > NAME_MAX:
        name = name[:-1]
    return path.with_name(f".{name}{suffix}")


@contextlib.contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield a temporary path to write; on success it is renamed to `path`, else removed.

    A library that fails to write it on a full disk without saying so (polars: "invalid
    thrift", rerun: "thread shut down") raises the system's error, ENOSPC, instead.
    """
    tmp = temporary_path(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException as exc:
        full = isinstance(exc, Exception) and not isinstance(exc, OSError) and _full(path)
        tmp.unlink(missing_ok=True)
        if full:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path)) from exc
        raise


def _full(path: Path) -> bool:
    """Whether the disk `path` is written to is full: less than FULL_BELOW_BYTES free."""
    try:
        disk = os.statvfs(path.parent)
    except OSError:
        return False
    return disk.f_bavail * disk.f_frsize < FULL_BELOW_BYTES


def write_text(path: Path, text: str) -> Path:
    """Write a text file atomically. Returns `path`."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


def write_bytes(path: Path, data: bytes) -> Path:
    """Write a binary file atomically. Returns `path`."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return path


def write_json(path: Path, document: Any) -> Path:
    """Write a JSON document atomically (indented; NaN and inf as null), where every iterator
    in it (a generator, not a list) is written as a list one item at a time, by json's own
    encoder: a long list is never held. Returns `path`."""
    encoder = json.JSONEncoder(indent=2, default=str)  # indented: the encoder in Python
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as stream:
        stream.writelines(encoder.iterencode(_finite(document)))
        stream.write("\n")
    return path


class _Items(list):  # type: ignore[type-arg]  # a list only to json's encoder
    """A non-empty iterator as json's encoder takes a list: item by item, never held."""

    def __init__(self, items: Iterator[Any]) -> None:
        super().__init__()
        self.items = items

    def __bool__(self) -> bool:
        return True

    def __iter__(self) -> Iterator[Any]:
        return map(_finite, self.items)


def write_parquet(frame: Any, path: Path) -> Path:
    """Write a polars frame as Parquet (zstd) atomically. Returns `path`."""
    with atomic_path(path) as tmp:
        frame.write_parquet(tmp, compression="zstd")
    return path


def _finite(value: Any) -> Any:
    """The document with every non-finite float (NaN, inf) replaced by None, every iterator
    made an `_Items`."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Iterator):
        first = next(value, _Items)  # a sentinel: the class itself
        return [] if first is _Items else _Items(itertools.chain([first], value))
    if isinstance(value, dict):
        return {str(k): _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value
