"""The logs a command names, checked before it does anything (a mistake is exit 2)."""

from __future__ import annotations

import os
import stat
from collections.abc import Sequence
from pathlib import Path

from impactlab.logs.inputs import NoLogs, require_log_names

MAGIC = b"\x89MCAP0\r\n"  # every MCAP file starts with it (impactlab.logs.reader.MAGIC)


def check_log_inputs(inputs: Sequence[str | Path]) -> None:
    """Each input names at least one log, and each named file starts as an MCAP file does.

    What a folder or pattern finds is read later: a damaged log there is the job's error
    (exit 1), while a named file that is missing or not a log is a mistake in the command.

    Raises:
        NoLogs: an input is missing, is not MCAP, or finds no log (exit 2, nothing done).
    """
    for item in inputs:
        _check_named(Path(item))
    _, empty = require_log_names(inputs)
    if empty:
        raise NoLogs(*empty[0])


def _check_named(path: Path) -> None:
    if path.is_dir() or (not path.exists() and any(c in str(path) for c in "*?[")):
        return  # a folder or a pattern: what it finds is checked by require_log_names
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a pipe named here never blocks
    except FileNotFoundError:
        raise NoLogs(str(path), "file not found") from None
    except OSError as exc:
        raise NoLogs(str(path), f"cannot read: {exc.strerror or exc}") from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise NoLogs(str(path), "not a regular file (a device, pipe or socket): not a log")
        magic = os.read(fd, len(MAGIC))
    finally:
        os.close(fd)
    if magic != MAGIC:
        hint = "; `impactlab record` records it" if path.suffix in (".toml", ".xml") else ""
        raise NoLogs(str(path), f"not an MCAP log{hint}")
