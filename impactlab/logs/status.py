"""Is a log complete? Its metadata records, read through its summary (the official reader)."""

from __future__ import annotations

import struct
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import make_reader

from impactlab.logs import format as logformat


def complete_metadata(path: Path) -> dict[str, dict[str, str]] | None:
    """The metadata records of a finished impactlab log, by name; None when it is not one.

    A log is finished when it has a summary and the `impactlab.outcome` record, which the
    writer adds last.
    """
    try:
        if not path.is_file():
            return None
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            if reader.get_summary() is None:
                return None
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    except (OSError, McapError, ValueError, EOFError, struct.error):
        return None
    if logformat.RUN_METADATA not in meta or logformat.OUTCOME_METADATA not in meta:
        return None
    return meta
