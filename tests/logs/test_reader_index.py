"""The reader takes a chunk's messages through its message indexes, checked against the chunk:
any index that disagrees with its chunk, in any entry, sends the chunk to the record-by-record
walk. Checked against the official reader."""

from __future__ import annotations

import io
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from mcap._chunk_builder import ChunkBuilder
from mcap.data_stream import RecordBuilder
from mcap.reader import make_reader
from mcap.records import Channel, DataEnd, Footer, Header, Message, MessageIndex, Schema
from mcap.writer import MCAP0_MAGIC
from mcap_conformance import write_chunk

from impactlab.logs.reader import read_mcap

Edit = Callable[[int, list[tuple[int, int]]], list[tuple[int, int]]]


def build(messages: list[Message], edit: Edit | None = None) -> bytes:
    """A file of one uncompressed chunk with its message indexes (passed through `edit`)."""
    out = RecordBuilder()
    out.write(MCAP0_MAGIC)
    Header(profile="", library="test").write(out)
    Schema(id=1, name="test.Bytes", encoding="", data=b"").write(out)
    for cid in (1, 2):
        Channel(id=cid, schema_id=1, topic=f"/c{cid}", message_encoding="", metadata={}).write(out)
    chunk = ChunkBuilder()
    for m in messages:
        chunk.add_message(m)
    write_chunk(out, chunk)
    for cid, index in chunk.message_indices.items():
        records = list(index.records) if edit is None else edit(cid, list(index.records))
        MessageIndex(channel_id=cid, records=records).write(out)
    DataEnd(data_section_crc=0).write(out)
    Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(out)
    out.write(MCAP0_MAGIC)
    return out.end()


def official(data: bytes) -> dict[str, list[tuple[int, bytes]]]:
    """Each topic's (log_time, payload) in time order, by the official reader."""
    out: dict[str, list[tuple[int, bytes]]] = {}
    for _, channel, message in make_reader(io.BytesIO(data)).iter_messages():
        out.setdefault(channel.topic, []).append((message.log_time, bytes(message.data)))
    return {topic: sorted(rows, key=lambda r: r[0]) for topic, rows in out.items()}


def ours(path: Path) -> tuple[dict[str, list[tuple[int, bytes]]], list[str]]:
    content = read_mcap(path)
    out = {}
    for channel in content.channels.values():
        rows = []
        for t, data in channel.pieces:
            payloads = data if isinstance(data, list) else [bytes(r) for r in data]
            rows += zip(t.tolist(), payloads, strict=True)
        out[channel.topic] = sorted(rows, key=lambda r: r[0])
    return out, content.problems


def interleaved(lengths1: list[int], lengths2: list[int], times2=None) -> list[Message]:
    """Channel 1 and 2 alternating, one message each per step, payloads of these lengths."""
    out = []
    for i, (a, b) in enumerate(zip(lengths1, lengths2, strict=True)):
        t2 = i * 10 if times2 is None else times2[i]
        out.append(Message(1, i * 10, bytes([i % 256]) * a, i * 10, sequence=2 * i))
        out.append(Message(2, t2, bytes([(i + 7) % 256]) * b, t2, sequence=2 * i + 1))
    return out


def test_evenly_spaced_records_of_several_lengths(tmp_path):
    """Channel 1 alternates 10- and 20-byte payloads, channel 2 the other way round."""
    n = 40
    messages = interleaved([10, 20] * (n // 2), [20, 10] * (n // 2))
    data = build(messages)
    path = tmp_path / "mixed.mcap"
    path.write_bytes(data)
    got, problems = ours(path)
    assert not problems
    assert got == official(data)


def test_records_of_one_length_are_one_array_per_chunk_and_channel(tmp_path):
    data = build(interleaved([13] * 50, [7] * 50))
    path = tmp_path / "even.mcap"
    path.write_bytes(data)
    got, problems = ours(path)
    assert not problems and got == official(data)
    for channel in read_mcap(path).channels.values():
        ((_, rows),) = channel.pieces
        assert rows.shape in ((50, 13), (50, 7))


def _shift_one_time(cid, records):
    if cid != 1:
        return records
    t, offset = records[len(records) // 2]
    records[len(records) // 2] = (t + 1, offset)
    return records


def _point_at_the_previous_record(cid, records):
    if cid != 1:
        return records
    records[5] = (records[5][0], records[4][1])
    return records


def _last_offset_past_the_chunk(cid, records):
    if cid != 1:
        return records
    step = records[1][1] - records[0][1]
    records[-1] = (records[-1][0], records[-1][1] + 1000 * step)
    return records


@pytest.mark.parametrize(
    "edit",
    [_shift_one_time, _point_at_the_previous_record, _last_offset_past_the_chunk],
    ids=["one-time", "one-offset", "offset-past-chunk"],
)
def test_an_index_wrong_in_one_entry_is_caught(tmp_path, edit):
    messages = interleaved([13] * 50, [7] * 50)
    data = build(messages, edit)
    path = tmp_path / "bad-index.mcap"
    path.write_bytes(data)
    got, problems = ours(path)
    assert any("message index" in p for p in problems)
    assert got == official(build(messages))  # nothing lost: the chunk is walked


def test_an_index_pointing_at_another_channel_is_caught(tmp_path):
    """Both channels log at the same times with payloads of one length: an index naming the
    wrong channel differs from its records only in their channel id."""
    messages = interleaved([9] * 30, [9] * 30)

    def swap(cid, records):
        # channel 1's index gets channel 2's offsets, evenly spaced, at the same times
        other = 2 if cid == 1 else 1
        mine = [m for m in messages if m.channel_id == other]
        base = records[0][1] + (31 + 9 if cid == 1 else -(31 + 9))
        return [(m.log_time, base + i * 2 * (31 + 9)) for i, m in enumerate(mine)]

    data = build(messages, swap)
    path = tmp_path / "swapped.mcap"
    path.write_bytes(data)
    got, problems = ours(path)
    assert any("message index" in p for p in problems)
    assert got == official(build(messages))


def test_one_message_per_channel(tmp_path):
    data = build([Message(1, 5, b"abc", 5, 0), Message(2, 6, b"", 6, 1)])
    path = tmp_path / "one.mcap"
    path.write_bytes(data)
    got, problems = ours(path)
    assert not problems and got == official(data)
    assert np.array_equal(read_mcap(path).channels[2].pieces[0][1].shape, (1, 0))
