"""The one place impactlab reaches into `mcap.writer.Writer`'s private state.

mcap has no public way to write a chunk assembled elsewhere: `Writer.add_message` takes one
message at a time (about 10 us each in Python). `ChunkWriter` (`chunks.py`) builds whole
chunks from arrays, writes them to the writer's stream itself and must then tell the writer
about them, so that the summary it writes (statistics, chunk indexes) counts them.

Written against mcap 1.6.0 (`MCAP_VERSION`): the name-mangled attributes in `PRIVATE`.
`tests/logs/test_mcap_internals.py` fails, naming the attribute, when an mcap release changes them.
"""

from __future__ import annotations

from typing import IO, Any

from mcap.records import ChunkIndex, Statistics
from mcap.writer import Writer

MCAP_VERSION = "1.6.0"
"""The mcap version this adapter was written and tested against."""

PRIVATE = (
    "_Writer__stream",
    "_Writer__record_builder",
    "_Writer__flush",
    "_Writer__chunk_indices",
    "_Writer__statistics",
)
"""Every private attribute of `mcap.writer.Writer` the adapter uses."""


class WriterInternals:
    """What `ChunkWriter` needs of a started `Writer` beyond its public methods."""

    def __init__(self, writer: Writer) -> None:
        self._writer = writer

    @property
    def stream(self) -> IO[bytes]:
        """The file the writer writes to (flushed: its position is the end of the data)."""
        self._writer._Writer__flush()  # type: ignore[attr-defined]
        stream: IO[bytes] = self._writer._Writer__stream  # type: ignore[attr-defined]
        return stream

    def write_record(self, record: Any) -> tuple[int, int]:
        """Write one `mcap.records` record at the end of the data: its (offset, length)."""
        start = self.stream.tell()
        builder = self._writer._Writer__record_builder  # type: ignore[attr-defined]
        record.write(builder)
        length = int(builder.count)
        self._writer._Writer__flush()  # type: ignore[attr-defined]
        return start, length

    def add_chunk_index(self, index: ChunkIndex) -> None:
        """Have the summary list a chunk written outside the writer."""
        self._writer._Writer__chunk_indices.append(index)  # type: ignore[attr-defined]

    @property
    def statistics(self) -> Statistics:
        """The Statistics record the writer will write (updated in place by the caller)."""
        stats: Statistics = self._writer._Writer__statistics  # type: ignore[attr-defined]
        return stats
