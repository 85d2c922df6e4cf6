"""Copying a log with the official mcap writer (the tests that rewrite a log: nudged values,
hostile metadata, another layout, odd metadata)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from mcap.records import Channel
from mcap.writer import Writer


def register_like(
    writer: Writer,
    summary: Any,
    rename: Callable[[Channel], tuple[str, dict[str, str]]] | None = None,
) -> dict[int, int]:
    """Register the schemas and channels of `summary` (an mcap reader's) with `writer`;
    returns the new channel id of each old one. `rename(channel)` gives another topic and
    channel metadata."""
    schemas = {
        sid: writer.register_schema(name=s.name, encoding=s.encoding, data=s.data)
        for sid, s in summary.schemas.items()
    }
    channels = {}
    for cid, c in summary.channels.items():
        topic, metadata = rename(c) if rename else (c.topic, dict(c.metadata))
        channels[cid] = writer.register_channel(
            topic=topic,
            message_encoding=c.message_encoding,
            schema_id=schemas[c.schema_id],
            metadata=metadata,
        )
    return channels
