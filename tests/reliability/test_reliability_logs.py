"""Broken and foreign logs: every command says what is wrong in one line, never crashes, and
still analyzes whatever complete data a damaged log holds (marked partial).

Damage is made on a small log written with small chunks (many chunks, so that cuts and
flipped bytes land between and inside chunks); chunk offsets come from the official reader's
summary. Foreign files are written with the official mcap writer.
"""

from __future__ import annotations

import contextlib
import json
import re
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from foxglove_schemas_protobuf.Log_pb2 import Log
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
from mcap_copy import register_like
from mcap_protobuf.schema import build_file_descriptor_set
from specs import drop, toml

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.cli import main
from impactlab.errors import LogError
from impactlab.logs.inputs import MAGIC
from impactlab.logs.load import RunLog, load_log
from impactlab.proto import impactlab_pb2 as pb
from impactlab.tools.info import describe

SPEC = toml(drop("fragile", z=0.3, max_time=0.6))
CHUNK_BYTES = 1 << 15  # about 70 logged steps per chunk: the 0.6 s run spans ~9 chunks
FOOTER_BYTES = 1 + 8 + 8 + 8 + 4 + 8  # footer record and closing magic


@pytest.fixture(scope="module")
def intact(tmp_path_factory) -> Path:
    """A complete log of a ball dropped on the plane (contacts included), in many chunks."""
    from impactlab.logs import writer
    from impactlab.record import plan, record_runs

    folder = tmp_path_factory.mktemp("fragile")
    spec = folder / "fragile.toml"
    spec.write_text(SPEC)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(writer, "CHUNK_BYTES", CHUNK_BYTES)
        (result,) = record_runs(plan([spec]), folder / "logs")
    return result.path


@pytest.fixture(scope="module")
def layout(intact: Path):
    """The intact log's bytes, chunk indexes (in file order) and summary offset."""
    with open(intact, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        footer = reader.get_footer() if hasattr(reader, "get_footer") else None
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    data = intact.read_bytes()
    summary_start = footer.summary_start if footer is not None else _summary_start(data)
    return data, chunks, summary_start


@pytest.fixture(scope="module")
def reference(intact: Path) -> RunLog:
    run = load_log(intact)
    assert not run.partial and run.outcome == "completed"
    assert run.contacts.height > 0  # the ball reaches the plane: contacts are logged too
    return run


def _summary_start(data: bytes) -> int:
    return int.from_bytes(data[-FOOTER_BYTES + 9 : -FOOTER_BYTES + 17], "little")


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    """Run the command line in-process; returns (exit code, stdout, stderr)."""
    code = main(list(argv))
    out, err = capsys.readouterr()
    assert "Traceback" not in err, err
    return code, out, err


def assert_error_line(err: str, path: Path) -> str:
    """Exactly one error line, naming the file: `impactlab: error: <path>: <problem>`."""
    lines = [line for line in err.splitlines() if line.startswith("impactlab: error:")]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"impactlab: error: {path}: "), lines[0]
    problem = lines[0].removeprefix(f"impactlab: error: {path}: ")
    assert problem.strip(), lines[0]
    return problem


def assert_prefix_of(run: RunLog, reference: RunLog) -> None:
    """Every frame of `run` holds rows of the intact log: same times, same values (exactly:
    both are decoded from the same bytes, no arithmetic involved)."""
    assert set(run.bodies) <= set(reference.bodies)
    for name, frame in run.bodies.items():
        full = reference.bodies[name]
        assert frame.height <= full.height
        t = frame["t_ns"].to_numpy()
        assert (np.diff(t) > 0).all()
        assert frame.equals(full.filter(pl.col("t_ns").is_in(t)))
    assert run.energy.height <= reference.energy.height
    t = run.energy["t_ns"].to_numpy()
    assert run.energy.equals(reference.energy.filter(pl.col("t_ns").is_in(t)))
    assert run.contacts.height <= reference.contacts.height
    t = run.contacts["t_ns"].to_numpy()
    assert run.contacts.equals(reference.contacts.filter(pl.col("t_ns").is_in(t)))


def assert_is_prefix(run: RunLog, reference: RunLog) -> None:
    """`run` holds the first rows of the intact log, with nothing missing in between."""
    assert_prefix_of(run, reference)
    for name, frame in run.bodies.items():
        assert frame.equals(reference.bodies[name].head(frame.height))


# ---------------------------------------------------------------------------------------------
# truncated logs


def records(data: bytes) -> list[tuple[int, int, int]]:
    """(opcode, start, end) of each top-level record."""
    out, pos = [], 8
    while pos + 9 <= len(data):
        end = pos + 9 + int.from_bytes(data[pos + 1 : pos + 9], "little")
        out.append((data[pos], pos, end))
        pos = end
    return out


def cut_points(layout) -> dict[str, int]:
    data, chunks, summary_start = layout
    first, second, middle = chunks[0], chunks[1], chunks[len(chunks) // 2]
    _, meta_start, meta_end = next(r for r in records(data) if r[0] == 0x0C)  # impactlab.run
    return {
        "empty": 0,
        "inside magic": 5,
        "magic only": 8,
        "inside header record": 12,
        "inside run metadata": meta_start + 20,
        "after run metadata": meta_end,
        "inside channels": (meta_end + first.chunk_start_offset) // 2,
        "before first chunk": first.chunk_start_offset,
        "inside first chunk": first.chunk_start_offset + first.chunk_length // 2,
        "inside first message index": first.chunk_start_offset + first.chunk_length + 5,
        "between chunks": second.chunk_start_offset,
        "inside middle chunk": middle.chunk_start_offset + middle.chunk_length // 3,
        "between middle chunks": middle.chunk_start_offset,
        "inside summary": summary_start + (len(data) - FOOTER_BYTES - summary_start) // 2,
        "just before footer": len(data) - FOOTER_BYTES,
        "before closing magic": len(data) - 8,
    }


CUTS = [
    "empty",
    "inside magic",
    "magic only",
    "inside header record",
    "inside run metadata",
    "after run metadata",
    "inside channels",
    "before first chunk",
    "inside first chunk",
    "inside first message index",
    "between chunks",
    "inside middle chunk",
    "between middle chunks",
    "inside summary",
    "just before footer",
    "before closing magic",
]
NO_DATA = {"empty", "inside magic", "magic only", "inside header record", "inside run metadata"}


@pytest.mark.slow
@pytest.mark.parametrize("cut", CUTS)
def test_truncated_log(tmp_path, capsys, intact, layout, reference, cut):
    data = layout[0]
    offset = cut_points(layout)[cut]
    bad = tmp_path / "cut.mcap"
    bad.write_bytes(data[:offset])
    out = tmp_path / "results"

    # analyze: the complete part is analyzed and marked partial; no data at all is an error
    # (not even MCAP's magic bytes, the only input: nothing to do, exit 2, nothing created)
    code, stdout, err = run_cli(capsys, "analyze", str(bad), "-o", str(out))
    if cut in NO_DATA:
        assert code == (2 if offset < 8 else 1)
        assert_error_line(err, bad)
        assert offset >= 8 or not out.exists()
    else:
        assert code == 0, err
        runs = pl.read_parquet(out / "runs.parquet")
        assert runs["partial"].to_list() == [True]
        assert f"impactlab: warning: {bad}: partial log" in err
        report = (out / "report.md").read_text()
        assert "partial" in report.lower() and "truncated" in report
        run = load_log(bad)
        assert run.partial and run.problems
        assert_is_prefix(run, reference)
        if offset >= layout[2]:  # cut after the data: nothing lost but the summary
            assert all(f.equals(reference.bodies[n]) for n, f in run.bodies.items())

    # info reads the summary: a truncated log has none
    code, stdout, err = run_cli(capsys, "info", str(bad))
    assert code == (2 if offset < 8 else 1)
    problem = assert_error_line(err, bad)
    if offset >= 8:
        assert "truncated" in problem or "summary" in problem

    # diff: unreadable input is exit 2; a readable partial log differs (1) or, cut after
    # the data, equals the intact one (0), with a warning that it is partial
    code, stdout, err = run_cli(capsys, "diff", str(intact), str(bad))
    if cut in NO_DATA:
        assert code == 2
        assert_error_line(err, bad)
    else:
        assert code == (0 if offset >= layout[2] else 1), stdout
        assert f"impactlab: warning: {bad}: " in err

    # replay: a recording of the complete part, with a warning; nothing for no data
    code, stdout, err = run_cli(capsys, "replay", str(bad), "-o", str(tmp_path / "rrd"))
    if cut in NO_DATA:
        assert code == (2 if offset < 8 else 1)
        assert_error_line(err, bad)
        assert not list(tmp_path.glob("rrd/*.rrd"))
    else:
        assert code == 0, err
        assert f"impactlab: warning: {bad}: " in err
        assert (tmp_path / "rrd" / "cut.rrd").stat().st_size > 0
    assert not list(tmp_path.rglob("*.partial"))


@pytest.mark.slow
def test_truncated_at_every_record_boundary(tmp_path, layout, reference):
    """Cut at each top-level record's start: load_log never fails on a cut after the first
    chunk, and always returns a prefix of the intact rows."""
    data, chunks, _ = layout
    bad = tmp_path / "cut.mcap"
    for _, offset, _ in records(data):
        bad.write_bytes(data[:offset])
        try:
            run = load_log(bad)
        except LogError:
            assert offset <= chunks[0].chunk_start_offset + chunks[0].chunk_length
            continue
        assert run.partial
        assert_is_prefix(run, reference)


# ---------------------------------------------------------------------------------------------
# corrupted chunk


def compressed_span(data: bytes, chunk) -> tuple[int, int]:
    """(start, end) byte offsets of a chunk record's compressed data."""
    at = chunk.chunk_start_offset + 9 + 8 + 8 + 8 + 4  # opcode, length, times, size, crc
    name_len = int.from_bytes(data[at : at + 4], "little")
    at += 4 + name_len
    size = int.from_bytes(data[at : at + 8], "little")
    assert size == chunk.compressed_size
    return at + 8, at + 8 + size


@pytest.mark.slow
def test_corrupted_middle_chunk(tmp_path, capsys, intact, layout, reference):
    data, all_chunks, _ = layout
    with open(intact, "rb") as stream:
        channels = make_reader(stream).get_summary().channels
    state = next(i for i, c in channels.items() if c.topic.endswith("/state"))
    # the chunks holding the ball's states (the contacts are written in chunks of their own)
    chunks = [c for c in all_chunks if state in c.message_index_offsets]
    k = len(chunks) // 2
    start, end = compressed_span(data, chunks[k])
    broken = bytearray(data)
    for i in range(start + (end - start) // 3, start + (end - start) // 3 + 8):
        broken[i] ^= 0x5A
    bad = tmp_path / "corrupt.mcap"
    bad.write_bytes(bytes(broken))

    run = load_log(bad)
    assert run.partial
    assert any("damaged" in p and "chunk" in p for p in run.problems), run.problems
    assert_is_prefix(run, reference)
    (ball,) = run.bodies.values()
    assert ball["t_ns"].max() < chunks[k].message_start_time  # the rows before the bad chunk
    assert ball["t_ns"].max() >= chunks[k - 1].message_end_time - 1  # ... all of them

    out = tmp_path / "results"
    code, stdout, err = run_cli(capsys, "analyze", str(bad), "-o", str(out))
    assert code == 0, err
    assert pl.read_parquet(out / "runs.parquet")["partial"].to_list() == [True]
    assert "damaged" in (out / "report.md").read_text()

    code, stdout, err = run_cli(capsys, "diff", str(intact), str(bad))
    assert code == 1 and "only in A" in stdout
    assert f"impactlab: warning: {bad}: damaged" in err

    code, stdout, err = run_cli(capsys, "replay", str(bad), "-o", str(tmp_path / "rrd"))
    assert code == 0 and f"impactlab: warning: {bad}: damaged" in err

    code, stdout, err = run_cli(capsys, "info", str(bad))  # the summary is intact
    assert code == 0 and "outcome:    completed" in stdout


def test_damaged_message_index_is_recovered(tmp_path, layout, reference):
    """Message indexes carry no CRC: one pointing at the wrong record is detected and the
    chunk is read record by record, losing nothing."""
    data, chunks, _ = layout
    first = chunks[0]
    at = min(first.message_index_offsets.values())
    # the first index record: opcode, length, channel id, pairs length, then (time, offset)s
    broken = bytearray(data)
    broken[at + 9 + 2 + 4 + 8] ^= 0x10  # the first message's offset
    bad = tmp_path / "index.mcap"
    bad.write_bytes(bytes(broken))
    run = load_log(bad)
    assert run.partial and any("message index" in p for p in run.problems)
    for name, frame in run.bodies.items():
        assert frame.equals(reference.bodies[name])
    assert run.energy.equals(reference.energy)
    assert run.contacts.equals(reference.contacts)


def test_damaged_metadata_is_named_and_the_rest_still_read(tmp_path, capsys, layout):
    """Metadata carry no CRC: a value that no longer parses is named (log and key). The
    masses are needed for the analysis, which refuses that log; diff, replay and info still
    read it. Every key and kind of damage: tests/reliability/test_reliability_metadata.py."""
    data = layout[0]
    at = data.rindex(b'"mass"')  # in the bodies record (the spec's comes first)
    broken = bytearray(data)
    broken[at + 8] = ord("x")  # "mass": x.0 ...
    bad = tmp_path / "meta.mcap"
    bad.write_bytes(bytes(broken))
    run = load_log(bad)
    assert run.partial and "bodies" in run.checked.problems
    assert any(p.startswith("metadata bodies: ") and "not valid JSON" in p for p in run.problems)
    code, _, err = run_cli(capsys, "analyze", str(bad), "-o", str(tmp_path / "out"))
    problem = assert_error_line(err, bad)
    assert code == 1 and problem.startswith("damaged metadata: bodies: ")
    code, _, err = run_cli(capsys, "diff", str(bad), str(bad))
    assert code == 0 and f"impactlab: warning: {bad}: metadata bodies: " in err
    code, _, err = run_cli(capsys, "replay", str(bad), "-o", str(tmp_path / "rrd"))
    assert code == 0 and (tmp_path / "rrd" / "meta.rrd").stat().st_size > 0
    code, stdout, err = run_cli(capsys, "info", str(bad))  # info shows the metadata as is
    assert code == 0 and "fragile" in stdout and "damaged:    metadata bodies: " in stdout


# ---------------------------------------------------------------------------------------------
# files that are not impactlab logs


def _official(path: Path, build, **options) -> Path:
    with open(path, "wb") as stream:
        writer = Writer(stream, **options)
        writer.start(profile="", library="another tool")
        build(writer)
        writer.finish()
    return path


def json_channels(writer: Writer) -> None:
    schema = writer.register_schema(
        name="Point", encoding="jsonschema", data=json.dumps({"type": "object"}).encode()
    )
    for topic in ("/points", "/bodies/ball/state"):
        channel = writer.register_channel(topic=topic, message_encoding="json", schema_id=schema)
        for i in range(50):
            data = json.dumps({"x": i * 0.1, "z": 1.0}).encode()
            writer.add_message(channel, log_time=i * 1000, data=data, publish_time=i * 1000)


def foxglove_log_only(writer: Writer) -> None:
    fds = build_file_descriptor_set(Log).SerializeToString()
    schema = writer.register_schema(name="foxglove.Log", encoding="protobuf", data=fds)
    for topic in ("/events", "/rosout"):
        channel = writer.register_channel(
            topic=topic, message_encoding="protobuf", schema_id=schema
        )
        for i in range(5):
            msg = Log(level=Log.INFO, message=f"hello {i}", name="other")
            msg.timestamp.FromNanoseconds(i * 1000)
            writer.add_message(
                channel, log_time=i * 1000, data=msg.SerializeToString(), publish_time=i * 1000
            )


def impactlab_schema_no_metadata(writer: Writer) -> None:
    fds = build_file_descriptor_set(pb.BodyState).SerializeToString()
    schema = writer.register_schema(name="impactlab.BodyState", encoding="protobuf", data=fds)
    channel = writer.register_channel(
        topic="/bodies/ball/state", message_encoding="protobuf", schema_id=schema
    )
    for i in range(200):
        msg = pb.BodyState(z=1.0 - 0.5 * 9.81 * (i * 1e-3) ** 2, vz=-9.81 * i * 1e-3, qw=1.0)
        writer.add_message(
            channel, log_time=i * 10**6, data=msg.SerializeToString(), publish_time=i * 10**6
        )


def metadata_only(writer: Writer) -> None:
    writer.add_metadata("calibration", {"k": "1"})


FOREIGN = {
    "json channels": (json_channels, {}),
    "json channels, unchunked": (json_channels, {"use_chunking": False}),
    "foxglove.Log only": (foxglove_log_only, {"compression": CompressionType.LZ4}),
    "impactlab schema, no metadata": (impactlab_schema_no_metadata, {}),
    "metadata only": (metadata_only, {}),
}


@pytest.mark.parametrize("kind", list(FOREIGN))
def test_foreign_mcap(tmp_path, capsys, kind):
    build, options = FOREIGN[kind]
    path = _official(tmp_path / "other.mcap", build, **options)

    code, _, err = run_cli(capsys, "analyze", str(path), "-o", str(tmp_path / "out"))
    assert code == 1
    problem = assert_error_line(err, path)
    assert "impactlab" in problem  # "not an impactlab log ...", "no impactlab.run metadata"

    code, _, err = run_cli(capsys, "diff", str(path), str(path))
    if kind == "impactlab schema, no metadata":  # readable messages: compared, with a warning
        assert code == 0 and "no impactlab.run metadata" in err
    else:
        assert code == 2
        assert_error_line(err, path)

    code, stdout, err = run_cli(capsys, "replay", str(path), "-o", str(tmp_path / "rrd"))
    if kind == "impactlab schema, no metadata":
        assert code == 0 and "no impactlab.run metadata" in err
    else:
        assert code == 1
        assert_error_line(err, path)

    # info describes any readable MCAP, and says when it is not an impactlab log
    code, stdout, err = run_cli(capsys, "info", str(path))
    assert code == 0, err
    assert "not an impactlab log" in stdout


@pytest.mark.slow
@pytest.mark.parametrize(
    "options",
    [
        {"use_chunking": False},
        {"compression": CompressionType.LZ4},
        {"compression": CompressionType.NONE},
        {"compression": CompressionType.ZSTD, "chunk_size": 4096, "enable_crcs": False},
    ],
    ids=["unchunked", "lz4", "uncompressed", "zstd-small-no-crc"],
)
def test_log_rewritten_by_official_writer(tmp_path, capsys, intact, reference, options):
    """An impactlab log copied record by record by the official writer, in another layout,
    reads the same."""
    copy = tmp_path / "copy.mcap"
    with open(intact, "rb") as src:
        reader = make_reader(src)
        summary = reader.get_summary()
        meta = list(reader.iter_metadata())
        attachments = list(reader.iter_attachments())
        messages = list(reader.iter_messages(log_time_order=False))

    def build(writer: Writer) -> None:
        channel_ids = register_like(writer, summary)
        for m in meta:
            writer.add_metadata(m.name, m.metadata)
        for _, channel, message in messages:
            writer.add_message(
                channel_ids[channel.id],
                log_time=message.log_time,
                data=message.data,
                publish_time=message.publish_time,
                sequence=message.sequence,
            )
        for a in attachments:
            writer.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)

    _official(copy, build, **options)
    run = load_log(copy)
    assert not run.partial, run.problems
    for name, frame in run.bodies.items():
        assert frame.equals(reference.bodies[name])
    assert run.energy.equals(reference.energy)
    assert run.contacts.equals(reference.contacts)
    assert run.events.equals(reference.events)
    code, stdout, err = run_cli(capsys, "diff", str(intact), str(copy))
    assert code == 0, stdout + err
    code, _, err = run_cli(capsys, "analyze", str(copy), "-o", str(tmp_path / "out"))
    assert code == 0, err


@pytest.mark.parametrize(
    ("name", "content"),
    [
        ("empty.mcap", b""),
        ("text.mcap", b"this is not a log\n" * 10),
        ("zip.mcap", b"PK\x03\x04" + bytes(200)),
        ("magic-only-garbage.mcap", b"\x89MCAP0\r\n" + bytes(range(256)) * 4),
    ],
)
def test_not_mcap(tmp_path, capsys, name, content):
    path = tmp_path / name
    path.write_bytes(content)
    for argv, expected in (
        # the only input, without MCAP's magic: nothing to do (2); with it, a damaged log (1)
        (["analyze", str(path), "-o", str(tmp_path / "out")], 1 + (content[:8] != MAGIC)),
        (["info", str(path)], 1 + (content[:8] != MAGIC)),
        (["diff", str(path), str(path)], 2),
        (["replay", str(path), "-o", str(tmp_path / "rrd")], 1 + (content[:8] != MAGIC)),
    ):
        code, _, err = run_cli(capsys, *argv)
        assert code == expected, (argv, err)
        problem = assert_error_line(err, path)
        assert re.search(r"not an MCAP file|not an impactlab log|truncated|damaged", problem)


def test_missing_and_folder(tmp_path, capsys):
    missing = tmp_path / "missing.mcap"
    code, _, err = run_cli(capsys, "info", str(missing))
    assert code == 2 and "file not found" in assert_error_line(err, missing)
    code, _, err = run_cli(capsys, "diff", str(missing), str(missing))
    assert code == 2
    folder = tmp_path / "folder.mcap"
    folder.mkdir()
    code, _, err = run_cli(capsys, "info", str(folder))
    assert code == 2 and "folder" in assert_error_line(err, folder)


@pytest.mark.slow
def test_one_bad_log_does_not_stop_the_others(tmp_path, capsys, intact):
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"garbage")
    code, stdout, err = run_cli(capsys, "analyze", str(bad), str(intact), "-o", str(tmp_path / "o"))
    assert code == 1
    assert_error_line(err, bad)
    assert pl.read_parquet(tmp_path / "o" / "runs.parquet").height == 1
    code, stdout, err = run_cli(capsys, "info", str(bad), str(intact))
    assert code == 1 and "fragile" in stdout


# ---------------------------------------------------------------------------------------------
# property: random truncation and flipped bytes


@st.composite
def damage(draw, size: int):
    cut = draw(st.one_of(st.just(size), st.integers(0, size)))
    flips = draw(st.lists(st.tuples(st.integers(0, size - 1), st.integers(1, 255)), max_size=4))
    return cut, flips


@pytest.mark.slow
@settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(data=st.data())
def test_random_damage(tmp_path, layout, reference, data):
    """Random cuts and flipped bytes: the reader either raises LogError or returns rows of the
    intact log (times sorted); analysis and info fail only with LogError.

    Chunks are CRC-checked and message indexes are checked against their chunk, so with
    flips only inside compressed chunk data the rows are exactly intact rows. A flip
    elsewhere (header, metadata, record lengths, summary) can change what the file says
    without any check noticing; there only the absence of crashes is guaranteed.
    """
    raw, chunks, _ = layout
    cut, flips = data.draw(damage(len(raw)))
    spans = [compressed_span(raw, c) for c in chunks]
    if data.draw(st.booleans()):  # half the examples: flips inside chunk data only
        flips = [
            (
                spans[i % len(spans)][0]
                + at % (spans[i % len(spans)][1] - spans[i % len(spans)][0]),
                x,
            )
            for i, (at, x) in enumerate(flips)
        ]
    broken = bytearray(raw[:cut])
    for at, x in flips:
        if at < len(broken):
            broken[at] ^= x
    in_chunks = all(any(a <= at < b for a, b in spans) for at, _ in flips)
    bad = tmp_path / "random.mcap"
    bad.write_bytes(bytes(broken))
    try:
        run = load_log(bad)
    except LogError:
        run = None
    if run is not None:
        if bytes(broken) != raw:
            assert run.partial or not in_chunks
        for frame in run.bodies.values():
            assert (np.diff(frame["t_ns"].to_numpy()) >= 0).all()
        if in_chunks:
            assert_is_prefix(run, reference)
        with contextlib.suppress(LogError):
            analyze_run(run)
    with contextlib.suppress(LogError):
        describe(bad)
