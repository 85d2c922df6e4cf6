"""The chunk writer: its dense path writes exactly the bytes of its general path, and what it
writes through mcap's Writer is in the file and in the summary (the official reader)."""

from __future__ import annotations

import io
from importlib.metadata import version

import numpy as np
import pytest
from mcap.reader import make_reader

from impactlab.logs import messages
from impactlab.logs.chunks import (
    MCAP_VERSION,
    PRIVATE,
    Block,
    ChunkWriter,
    Index,
    _ChunkIndex,
    _dense,
    _loose,
)


def _blocks(rng: np.random.Generator, n: int, subset_times: bool) -> list[Block]:
    t = np.cumsum(rng.integers(1, 5, n)).astype(np.int64) * 500_000
    tf = messages.stamped_transforms(("A", "B"), t, rng.normal(size=(n, 14)))
    blocks = [
        Block(1, t[:1], rng.integers(0, 256, (1, 37), dtype=np.uint8)),  # a scene, raw bytes
        Block(2, t, messages.body_state().encode(rng.normal(size=(n, 13)))),
        Block(3, t, messages.clearance(2).encode(rng.normal(size=(n, 2)))),
        Block(5, t, messages.energy().encode(rng.normal(size=(n, 3)))),
        *(Block(6, t[rows], payloads) for rows, payloads in tf),  # stamps of several lengths
    ]
    some = rng.random(n) < 0.4  # a block at some rows only, as contacts were
    values = rng.normal(size=(int(some.sum()), 13))
    blocks.insert(3, Block(4, t[some], messages.clearance(13).encode(values)))
    if not subset_times:  # times no other block has: the union has to be sorted
        extra = np.sort(rng.choice(np.arange(1, 10 * n), n // 3, replace=False)) * 100_001
        payloads = messages.energy().encode(rng.normal(size=(extra.size, 3)))
        blocks.append(Block(7, extra.astype(np.int64), payloads))
    return blocks


@pytest.mark.parametrize("subset_times", [True, False])
@pytest.mark.parametrize("n", [1, 2, 50, 777])
def test_dense_records_equal_the_general_path(n, subset_times):
    rng = np.random.default_rng(n)
    blocks = [b for b in _blocks(rng, n, subset_times) if len(b.log_time)]
    fast, fast_index = _dense(blocks)
    slow, slow_index = _loose(blocks)
    assert bytes(fast) == bytes(slow)
    assert (fast_index.channels == slow_index.channels).all()
    assert (fast_index.counts == slow_index.counts).all()
    assert (fast_index.pairs == slow_index.pairs).all()


def test_mcap_is_the_version_the_adapter_was_written_for():
    """A new mcap: check impactlab/logs/chunks.py against it, then bump MCAP_VERSION."""
    assert version("mcap") == MCAP_VERSION, (
        f"mcap {version('mcap')} installed, impactlab/logs/chunks.py written for {MCAP_VERSION}: "
        f"check the private attributes it uses ({', '.join(PRIVATE)})"
    )


def test_chunks_written_through_the_adapter_are_in_the_file_and_its_summary():
    stream = io.BytesIO()
    out = ChunkWriter(stream, library="test")
    a = out.channel("/a", "impactlab.Energy", b"", {"k": "v"})
    b = out.channel("/b", "impactlab.Energy", b"", {})
    out.writer.add_metadata("m", {"k": "v"})  # writes the channels out before the chunks
    t = np.arange(5, dtype=np.int64) * 10
    payloads = messages.energy().encode(np.arange(15.0).reshape(5, 3))
    out.write_chunk([Block(a, t, payloads), Block(b, t[1:3], [b"x", b"yz"])])
    out.write_chunk([Block(b, t + 100, payloads)])
    with pytest.raises(RuntimeError, match="before the first chunk"):
        out.channel("/late", "impactlab.Energy", b"", {})
    out.wait()  # the adapter's thread writes the chunks: then the Writer's records
    out.writer.finish()
    out.close()
    reader = make_reader(io.BytesIO(stream.getvalue()))
    summary = reader.get_summary()
    assert summary.statistics.message_count == 12 and summary.statistics.chunk_count == 2
    assert dict(summary.statistics.channel_message_counts) == {a: 5, b: 7}
    assert len(summary.chunk_indexes) == 2
    got = [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages(log_time_order=False)]
    assert got[:3] == [
        ("/a", 0, payloads[0].tobytes()),
        ("/a", 10, payloads[1].tobytes()),
        ("/b", 10, b"x"),
    ]
    assert [m.log_time for _, _, m in reader.iter_messages()] == sorted(x[1] for x in got)


@pytest.mark.parametrize("data", [b"", b"<mujoco/>", bytes(range(256)) * 999])
def test_an_attachment_is_the_bytes_mcaps_writer_writes_and_in_the_summary(data):
    streams = io.BytesIO(), io.BytesIO()
    ours, theirs = (ChunkWriter(s, library="test") for s in streams)
    ours.attach("model.xml", "application/xml", data)
    theirs.writer.add_attachment(0, 0, "model.xml", "application/xml", data)
    for out in (ours, theirs):
        out.writer.finish()
    assert streams[0].getvalue() == streams[1].getvalue()
    reader = make_reader(io.BytesIO(streams[0].getvalue()))
    (attachment,) = reader.iter_attachments()
    assert (attachment.name, attachment.media_type, attachment.data) == (
        "model.xml",
        "application/xml",
        data,
    )


@pytest.mark.parametrize("offsets", [{}, {1: 0}, {2: 2**40, 1: 5, 65535: 2**64 - 1}])
def test_a_chunk_index_is_the_bytes_mcaps_record_writes(offsets):
    from mcap.data_stream import RecordBuilder
    from mcap.records import ChunkIndex

    fields = dict(
        message_start_time=3, message_end_time=2**63, chunk_start_offset=99,
        chunk_length=12_345, message_index_offsets=offsets, message_index_length=77,
        compression="zstd", compressed_size=5, uncompressed_size=2**33,
    )  # fmt: skip
    ours, theirs = RecordBuilder(), RecordBuilder()
    _ChunkIndex(**fields).write(ours)
    ChunkIndex(**fields).write(theirs)
    assert ours.end() == theirs.end()


@pytest.mark.parametrize("counts", [[1], [3, 3, 3], [2, 2, 1, 4, 4], [5, 1, 1]])
def test_message_indexes_are_the_bytes_mcaps_records_write(counts):
    from mcap.data_stream import RecordBuilder
    from mcap.records import MessageIndex

    rng = np.random.default_rng(len(counts))
    channels = np.sort(rng.choice(2**16, len(counts), replace=False))
    pairs = rng.integers(0, 2**63, (sum(counts), 2))
    records, starts = Index(channels, np.array(counts), pairs).records()
    theirs, first, at = RecordBuilder(), 0, []
    for channel, count in zip(channels.tolist(), counts, strict=True):
        at.append(theirs.count)
        rows = [tuple(row) for row in pairs[first : first + count].tolist()]
        MessageIndex(channel, rows).write(theirs)
        first += count
    assert bytes(records) == theirs.end()
    assert starts.tolist() == at


def _energy_block(channel: int, t0: int, n: int) -> Block:
    t = t0 + np.arange(n, dtype=np.int64)
    return Block(channel, t, messages.energy().encode(np.arange(3.0 * n).reshape(n, 3)))


def test_large_chunks_written_by_the_thread_keep_their_order_with_small_ones():
    stream = io.BytesIO()
    out = ChunkWriter(stream, library="test")
    a = out.channel("/a", "impactlab.Energy", b"", {})
    out.writer.add_metadata("m", {})
    sizes = [20_000, 3, 20_000, 20_000, 5]  # a chunk of 20,000 is 1.2 MB: the thread's
    t0 = np.cumsum([0, *sizes[:-1]])
    for start, n in zip(t0.tolist(), sizes, strict=True):
        out.write_chunk([_energy_block(a, start, n)])
    out.attach("model.xml", "application/xml", b"<mujoco/>")  # after every chunk
    out.writer.finish()
    out.close()
    reader = make_reader(io.BytesIO(stream.getvalue()))
    summary = reader.get_summary()
    assert summary.statistics.chunk_count == len(sizes)
    assert summary.statistics.message_count == sum(sizes)
    times = [m.log_time for _, _, m in reader.iter_messages(log_time_order=False)]
    assert times == list(range(sum(sizes)))
    assert [x.name for x in reader.iter_attachments()] == ["model.xml"]


class _FullDisk(io.BytesIO):
    def write(self, data) -> int:  # type: ignore[no-untyped-def, override]
        if self.tell() > 1 << 20:
            raise OSError(28, "No space left on device")
        return super().write(data)


def test_a_failure_of_the_thread_is_raised_to_the_caller():
    out = ChunkWriter(_FullDisk(), library="test")
    a = out.channel("/a", "impactlab.Energy", b"", {})
    out.writer.add_metadata("m", {})
    with pytest.raises(OSError, match="No space left"):
        for i in range(10):
            out.write_chunk([_energy_block(a, i * 20_000, 20_000)])
        out.wait()
    out.close()
