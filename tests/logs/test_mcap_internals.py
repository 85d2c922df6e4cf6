"""The mcap writer's private state that `impactlab.logs.mcap_internals` reaches into is still
there: these tests fail by name when an mcap release changes it (the adapter's docstring says
which version it was written for)."""

from __future__ import annotations

import io
from importlib.metadata import version

from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Metadata, Statistics
from mcap.stream_reader import StreamReader
from mcap.writer import Writer

from impactlab.logs.mcap_internals import MCAP_VERSION, PRIVATE, WriterInternals


def started() -> tuple[io.BytesIO, Writer]:
    stream = io.BytesIO()
    writer = Writer(stream)
    writer.start(profile="", library="test")
    return stream, writer


def test_mcap_is_the_version_the_adapter_was_written_for():
    """A new mcap: check impactlab/logs/mcap_internals.py against it, then bump MCAP_VERSION."""
    assert version("mcap") == MCAP_VERSION, (
        f"mcap {version('mcap')} installed, impactlab/logs/mcap_internals.py written for "
        f"{MCAP_VERSION}: check the private attributes it uses ({', '.join(PRIVATE)})"
    )


def test_mcap_writer_still_has_the_private_state_chunk_writing_uses():
    _, writer = started()
    missing = [name for name in PRIVATE if not hasattr(writer, name)]
    assert not missing, f"mcap.writer.Writer has no {missing} (impactlab/logs/mcap_internals.py)"
    assert hasattr(writer._Writer__record_builder, "count")  # type: ignore[attr-defined]
    stats = writer._Writer__statistics  # type: ignore[attr-defined]
    assert isinstance(stats, Statistics)
    for field in ("message_count", "message_start_time", "message_end_time", "chunk_count"):
        assert isinstance(getattr(stats, field), int), field
    assert isinstance(writer._Writer__chunk_indices, list)  # type: ignore[attr-defined]


def test_a_record_written_through_the_adapter_is_in_the_file_and_the_summary():
    """The adapter writes where the writer would, and what it adds to the statistics and the
    chunk indexes is what the writer's summary then holds."""
    stream, writer = started()
    internals = WriterInternals(writer)
    offset, length = internals.write_record(Metadata(name="m", metadata={"k": "v"}))
    internals.statistics.metadata_count += 1
    writer.finish()
    data = stream.getvalue()
    assert data[offset] == Opcode.METADATA and offset + length < len(data)
    records = list(StreamReader(io.BytesIO(data)).records)
    found = [(r.name, r.metadata) for r in records if isinstance(r, Metadata)]
    assert found == [("m", {"k": "v"})]
    summary = make_reader(io.BytesIO(data)).get_summary()
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.metadata_count == 1
