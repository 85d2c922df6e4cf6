"""The MCAP conformance suite's input files, made with the MCAP project's own Python records.

The suite (github.com/foxglove/mcap, tests/conformance) holds one small file per input and per
combination of writer features: chunks, message indexes, statistics, repeated schemas and
channels, attachment and metadata indexes, chunk indexes, summary offsets, and records padded
with extra bytes a reader must skip. Its files are stored with Git LFS, so this module makes
them again: `variants()` ports `scripts/generate-inputs.ts` and `variants/*.ts` (same inputs,
same feature combinations and rules, same record order and padding), writing every record
with the `mcap` package's `records` and `RecordBuilder`. Checked against the suite's expected
JSON records of every variant (upstream commit 95d067356): the same records, fields and CRCs.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from itertools import combinations

from mcap._chunk_builder import ChunkBuilder
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Message,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.writer import MCAP0_MAGIC

# the suite's feature names, in its order (variants/types.ts)
FEATURES = ("ch", "mx", "st", "rsh", "rch", "ax", "mdx", "chx", "sum", "pad")
PADDING = b"\x01\xff\xff"
UNPADDED = {Opcode.FOOTER, Opcode.MESSAGE, Opcode.CHUNK, Opcode.DATA_END}


def _ten_messages() -> list:
    times = [0, 2, 1, 3, 3, 5, 4, 7, 8, 9]  # not in order, on purpose
    return [
        Message(channel_id=1, log_time=t, publish_time=t, data=bytes([1, 2, 3]), sequence=i)
        for i, t in enumerate(times)
    ]


def _schema() -> Schema:
    return Schema(id=1, name="Example", encoding="c", data=bytes([4, 5, 6]))


def _channel(schema_id: int = 1, encoding: str = "a", metadata=None) -> Channel:
    return Channel(
        id=1,
        topic="example",
        schema_id=schema_id,
        message_encoding=encoding,
        metadata={"foo": "bar"} if metadata is None else metadata,
    )


def _message() -> Message:
    return Message(channel_id=1, log_time=2, publish_time=1, data=bytes([1, 2, 3]), sequence=10)


INPUTS = {
    "NoData": lambda: [],
    "OneSchemalessMessage": lambda: [_channel(0, "text", {}), _message()],
    "OneMessage": lambda: [_schema(), _channel(), _message()],
    "OneAttachment": lambda: [
        Attachment(
            name="myFile",
            media_type="application/octet-stream",
            log_time=2,
            create_time=1,
            data=bytes([1, 2, 3]),
        )
    ],
    "OneMetadata": lambda: [Metadata(name="myMetadata", metadata={"foo": "bar"})],
    "TenMessages": lambda: [_schema(), _channel(), *_ten_messages()],
}


@dataclass(frozen=True)
class Variant:
    """One conformance file: its name (`OneMessage-ch-mx-st`), input and features."""

    name: str
    input: str
    features: frozenset[str]

    def build(self) -> bytes:
        """The file's bytes."""
        return generate(self.features, INPUTS[self.input]())

    @property
    def has_summary(self) -> bool:
        """Whether the footer points at a summary section."""
        return bool(self.features & {"st", "rsh", "rch", "ax", "mdx", "chx"})


def variants() -> Iterator[Variant]:
    """Every variant of the suite, in a stable order (416 files)."""
    for name, make in INPUTS.items():
        records = make()
        kinds = {type(r) for r in records}
        for n in range(len(FEATURES) + 1):
            for combo in combinations(FEATURES, n):
                features = frozenset(combo)
                if _valid(features, kinds):
                    yield Variant("-".join([name, *sorted(features)]), name, features)


def _valid(f: frozenset[str], kinds: set[type]) -> bool:
    """The suite's rules for which features make sense for an input (generateTestVariants)."""
    if "ax" in f and Attachment not in kinds:
        return False
    if "mdx" in f and Metadata not in kinds:
        return False
    if "rsh" in f and Schema not in kinds:
        return False
    if "rch" in f and Channel not in kinds:
        return False
    if not kinds & {Message, Channel, Schema} and f & {"ch", "chx", "mx"}:
        return False
    if "sum" in f and not f & {"chx", "rsh", "rch", "mdx", "ax", "st"}:
        return False
    return not (f & {"chx", "mx"} and "ch" not in f)


class _Builder(RecordBuilder):
    """A record builder that pads records with extra bytes, as the suite's `pad` feature."""

    def __init__(self, pad: bool) -> None:
        super().__init__()
        self._pad = pad
        self._op = 0

    def start_record(self, opcode: Opcode) -> None:
        self._op = opcode
        super().start_record(opcode)

    def finish_record(self) -> None:
        if self._pad and self._op not in UNPADDED:
            self.write(PADDING)
        super().finish_record()

    def length(self) -> int:
        return self._buffer.tell()

    def pad_record_at(self, start: int) -> None:
        """Pad the record written at `start` by another writer (the Attachment record)."""
        if self._pad:
            self.write(PADDING)
            end = self.length()
            self._buffer.seek(start + 1)
            self._buffer.write(struct.pack("<Q", end - start - 9))
            self._buffer.seek(end)

    def data(self) -> bytes:
        return self._buffer.getvalue()


def write_chunk(out: RecordBuilder, chunk: ChunkBuilder) -> bytes:
    """Write `chunk`'s messages as one uncompressed Chunk record; returns its data."""
    raw = chunk.end()
    Chunk(
        compression="",
        data=raw,
        message_start_time=chunk.message_start_time,
        message_end_time=chunk.message_end_time,
        uncompressed_crc=zlib.crc32(raw),
        uncompressed_size=len(raw),
    ).write(out)
    return raw


def _written(builder: _Builder, record) -> tuple[int, int]:
    """Write a record; returns (offset, length) of it."""
    start = builder.length()
    record.write(builder)
    if isinstance(record, Attachment):  # written with its own builder, which does not pad
        builder.pad_record_at(start)
    return start, builder.length() - start


def generate(features: frozenset[str], records: list) -> bytes:
    """One file of the suite (a port of generate-inputs.ts `generateFile`)."""
    out = _Builder("pad" in features)
    out.write(MCAP0_MAGIC)
    Header(profile="", library="").write(out)
    chunk = ChunkBuilder() if "ch" in features else None
    meta_idx, att_idx, chunk_idx = [], [], []
    counts: dict[int, int] = {}
    times: list[int] = []
    n_schemas = n_channels = n_att = n_meta = 0
    for r in records:
        if isinstance(r, Schema):
            n_schemas += 1
            chunk.add_schema(r) if chunk else r.write(out)
        elif isinstance(r, Channel):
            n_channels += 1
            chunk.add_channel(r) if chunk else r.write(out)
        elif isinstance(r, Message):
            counts[r.channel_id] = counts.get(r.channel_id, 0) + 1
            times.append(r.log_time)
            chunk.add_message(r) if chunk else r.write(out)
        elif isinstance(r, Attachment):
            n_att += 1
            offset, length = _written(out, r)
            if "ax" in features:
                att_idx.append(
                    AttachmentIndex(
                        offset=offset,
                        length=length,
                        log_time=r.log_time,
                        create_time=r.create_time,
                        data_size=len(r.data),
                        name=r.name,
                        media_type=r.media_type,
                    )
                )
        elif isinstance(r, Metadata):
            n_meta += 1
            offset, length = _written(out, r)
            if "mdx" in features:
                meta_idx.append(MetadataIndex(offset=offset, length=length, name=r.name))
    if chunk is not None:
        start = out.length()
        raw = write_chunk(out, chunk)
        chunk_length = out.length() - start
        offsets, index_length = {}, 0
        if "mx" in features:
            for channel_id, index in chunk.message_indices.items():
                offsets[channel_id], length = _written(out, index)
                index_length += length
        if "chx" in features:
            chunk_idx.append(
                ChunkIndex(
                    message_start_time=chunk.message_start_time,
                    message_end_time=chunk.message_end_time,
                    chunk_start_offset=start,
                    chunk_length=chunk_length,
                    message_index_offsets=offsets,
                    message_index_length=index_length,
                    compression="",
                    compressed_size=len(raw),
                    uncompressed_size=len(raw),
                )
            )
    DataEnd(data_section_crc=zlib.crc32(out.data())).write(out)
    summary_start = out.length()
    groups: list[tuple[Opcode, int, int]] = []

    def group(opcode: Opcode, items: list) -> None:
        start = out.length()
        for item in items:
            item.write(out)
        if out.length() > start:
            groups.append((opcode, start, out.length() - start))

    group(Opcode.SCHEMA, [r for r in records if isinstance(r, Schema)] if "rsh" in features else [])
    group(
        Opcode.CHANNEL, [r for r in records if isinstance(r, Channel)] if "rch" in features else []
    )
    if "st" in features:
        stats = Statistics(
            message_count=len(times),
            schema_count=n_schemas,
            channel_count=n_channels,
            attachment_count=n_att,
            metadata_count=n_meta,
            chunk_count=1 if chunk is not None else 0,
            message_start_time=min(times, default=0),
            message_end_time=max(times, default=0),
            channel_message_counts=counts,
        )
        group(Opcode.STATISTICS, [stats])
    group(Opcode.METADATA_INDEX, meta_idx)
    group(Opcode.ATTACHMENT_INDEX, att_idx)
    group(Opcode.CHUNK_INDEX, chunk_idx)
    has_summary = out.length() != summary_start
    offset_start = 0
    if "sum" in features:
        offset_start = out.length()
        for opcode, start, length in groups:
            SummaryOffset(group_opcode=opcode, group_start=start, group_length=length).write(out)
    summary_at = summary_start if has_summary else 0
    crc = zlib.crc32(out.data()[summary_start:])
    crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_at, offset_start), crc)
    Footer(summary_start=summary_at, summary_offset_start=offset_start, summary_crc=crc).write(out)
    out.write(MCAP0_MAGIC)
    return out.data()
