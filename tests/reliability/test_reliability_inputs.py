"""Inputs that are not what a log should be: files that never end, decompression bombs, files
too large, MCAP files from other writers (the MCAP conformance suite), and odd folders.

Every command (analyze, diff, replay, info) answers each with one line naming the input, a
non-zero exit code where it is an error, and no traceback; reads end, and take no more memory
than the file's declared contents allow.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import zlib
from collections import Counter
from pathlib import Path

import lz4.frame
import pytest
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.records import Chunk, DataEnd, Footer, Header
from mcap.writer import MCAP0_MAGIC
from mcap_conformance import Variant, variants
from specs import drop, toml

from impactlab.cli import main
from impactlab.errors import LogError
from impactlab.logs.load import load_log
from impactlab.tools.info import describe

MAX_LOG_BYTES_ENV = "IMPACTLAB_MAX_LOG_BYTES"  # documented in docs/log-format.md
MAX_CHUNK_MIB = 256

COMMANDS = {  # command -> (argv for an input, the exit code of an unreadable input)
    "analyze": (lambda p, t: ["analyze", str(p), "-o", str(t / "out")], 1),
    "diff": (lambda p, t: ["diff", str(p), str(p)], 2),
    "replay": (lambda p, t: ["replay", str(p), "-o", str(t / "rrd")], 1),
    "info": (lambda p, t: ["info", str(p)], 1),
}


class Hang(Exception):
    pass


def run_cli(capsys, argv: list[str], *, seconds: int = 60) -> tuple[int, str, str]:
    """Run the command line in-process, failing (not hanging) if it does not end in time."""

    def alarm(signum, frame):
        raise Hang(f"{argv} did not end within {seconds} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        code = main(argv)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    out, err = capsys.readouterr()
    assert "Traceback" not in err, err
    return code, out, err


GUARD = """
import contextlib, io, json, resource, signal, sys
resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))  # a read that never ends fails here
from impactlab.cli import main
import impactlab.analyze.job, impactlab.tools.diff, impactlab.replay.recordings
def alarm(signum, frame):
    raise TimeoutError("did not end within 60 s")
signal.signal(signal.SIGALRM, alarm)
def peak_kb():  # VmHWM: unlike ru_maxrss, not inherited over exec from pytest's worker
    return next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:"))
base = peak_kb()
for line in sys.stdin:
    argv = json.loads(line)
    err = io.StringIO()
    signal.alarm(60)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(argv)
    except BaseException as exc:
        code, err = -1, io.StringIO(f"{type(exc).__name__}: {exc}")
    signal.alarm(0)
    grown = (peak_kb() - base) // 1024
    print(json.dumps([code, err.getvalue(), grown]), flush=True)
"""


def guarded(runs: list[list[str]]) -> list[tuple[int, str, int]]:
    """Run command lines in a fresh process whose memory is capped at 4 GiB and whose every
    command is stopped after 60 s (a hang guard: each takes well under a second): (exit code, stderr, peak memory growth in MiB) of each."""
    lines = "".join(json.dumps(argv) + "\n" for argv in runs)
    done = subprocess.run(
        [sys.executable, "-c", GUARD], input=lines, capture_output=True, text=True, timeout=300
    )
    results = [tuple(json.loads(line)) for line in done.stdout.splitlines()]
    assert len(results) == len(runs), done.stderr[-2000:]
    return results  # type: ignore[return-value]


def error_line(err: str, path: Path | str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("impactlab: error:")]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"impactlab: error: {path}: "), lines[0]
    return lines[0].removeprefix(f"impactlab: error: {path}: ")


# ---------------------------------------------------------------------------------------------
# reads that would never end


def special_files(tmp_path: Path) -> dict[str, Path]:
    fifo = tmp_path / "fifo.mcap"
    os.mkfifo(fifo)  # opening it for reading blocks until a writer comes: none will
    zero = tmp_path / "zero.mcap"
    zero.symlink_to("/dev/zero")  # endless zeros
    sock = tmp_path / "socket.mcap"
    server = socket.socket(socket.AF_UNIX)
    server.bind(str(sock))
    return {"/dev/zero": Path("/dev/zero"), "fifo": fifo, "link to /dev/zero": zero, "socket": sock}


@pytest.mark.slow
def test_what_is_not_a_regular_file_is_refused(tmp_path):
    files = special_files(tmp_path)
    cases = [(command, name, path) for command in COMMANDS for name, path in files.items()]
    results = guarded([COMMANDS[command][0](path, tmp_path) for command, _, path in cases])
    for (command, name, path), (code, err, _) in zip(cases, results, strict=True):
        assert code == 2, (command, name, err)  # the only input, not a log: nothing to do
        assert "Traceback" not in err
        assert "not a regular file" in error_line(err, path), (command, name)


def bomb(path: Path, *, compression: str, inflated: int, declared: int) -> Path:
    """An MCAP file whose one chunk inflates to `inflated` zero bytes and declares `declared`."""
    zeros = bytes(1 << 20)
    if compression == "zstd":
        compressor = zstandard.ZstdCompressor(level=1).compressobj(size=inflated)
        data = b"".join(compressor.compress(zeros) for _ in range(inflated >> 20))
        data += compressor.flush()
    else:
        compressor = lz4.frame.LZ4FrameCompressor()
        data = compressor.begin() + b"".join(
            compressor.compress(zeros) for _ in range(inflated >> 20)
        )
        data += compressor.flush()
    crc = 0
    for _ in range(declared >> 20):
        crc = zlib.crc32(zeros, crc)
    out = RecordBuilder()
    out.write(MCAP0_MAGIC)
    Header(profile="", library="bomb").write(out)
    Chunk(
        compression=compression,
        data=data,
        message_start_time=0,
        message_end_time=0,
        uncompressed_crc=crc,
        uncompressed_size=declared,
    ).write(out)
    DataEnd(data_section_crc=0).write(out)
    Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(out)
    out.write(MCAP0_MAGIC)
    path.write_bytes(out.end())
    return path


GIB = 1 << 30
BOMBS = {
    # the chunk says what it is: refused before decompressing
    "zstd, declares 1 GiB": ("zstd", GIB, GIB),
    # the chunk claims 1 MiB, its zstd frame says 1 GiB: never more than 1 MiB is inflated
    "zstd, declares 1 MiB": ("zstd", GIB, 1 << 20),
    "lz4, declares 1 MiB": ("lz4", GIB // 4, 1 << 20),
}


@pytest.mark.slow
@pytest.mark.parametrize("kind", list(BOMBS))
def test_decompression_bombs_are_stopped_at_the_declared_size(tmp_path, kind):
    compression, inflated, declared = BOMBS[kind]
    path = bomb(
        tmp_path / "bomb.mcap", compression=compression, inflated=inflated, declared=declared
    )
    assert path.stat().st_size < 5_000_000
    results = guarded([argv(path, tmp_path) for argv, _ in COMMANDS.values()])
    for (command, (_, code)), (got, err, grown) in zip(COMMANDS.items(), results, strict=True):
        assert got == code, (command, err)
        problem = error_line(err, path)
        if declared > MAX_CHUNK_MIB << 20:
            assert f"more than the limit of {MAX_CHUNK_MIB}.0 MiB per chunk" in problem, problem
        else:
            assert "CRC or size mismatch" in problem, problem
        # peak memory: the inflated size is never held
        assert grown < 100, f"{command} grew by {grown} MiB reading a {inflated >> 20} MiB bomb"


@pytest.mark.slow
def test_the_size_limit_is_documented_and_settable(tmp_path, capsys, monkeypatch):
    from impactlab.logs import writer
    from impactlab.record import plan, record_runs

    (tmp_path / "limits.toml").write_text(SMALL_SPEC)
    with monkeypatch.context() as patch:
        patch.setattr(writer, "CHUNK_BYTES", 1 << 15)  # many chunks of 32 KiB
        (result,) = record_runs(plan([tmp_path / "limits.toml"]), tmp_path / "logs")
    log = result.path
    size = log.stat().st_size
    monkeypatch.setenv(MAX_LOG_BYTES_ENV, str(size // 2))  # the file alone is over it
    with pytest.raises(LogError, match=f"more than the limit.*{MAX_LOG_BYTES_ENV}"):
        load_log(log)
    monkeypatch.setenv(MAX_LOG_BYTES_ENV, str(size + 200_000))  # the chunks run over it
    run = load_log(log)
    assert run.partial and any("exceed the limit" in p for p in run.problems), run.problems
    assert 0 < run.bodies["ball"].height < 1001  # the chunks before the limit
    monkeypatch.setenv(MAX_LOG_BYTES_ENV, "lots")
    code, _, err = run_cli(capsys, ["analyze", str(log), "-o", str(tmp_path / "out")])
    assert code == 1 and MAX_LOG_BYTES_ENV in error_line(err, log)
    monkeypatch.delenv(MAX_LOG_BYTES_ENV)
    assert not load_log(log).partial


SMALL_SPEC = toml(drop("limits", z=0.3))


# ---------------------------------------------------------------------------------------------
# MCAP files of other writers: the conformance suite


@pytest.fixture(scope="module")
def conformance(tmp_path_factory) -> dict[str, tuple[Variant, Path]]:
    folder = tmp_path_factory.mktemp("conformance")
    out = {}
    for variant in variants():
        path = folder / f"{variant.name}.mcap"
        path.write_bytes(variant.build())
        out[variant.name] = (variant, path)
    return out


def test_the_suite_is_complete(conformance):
    assert len(conformance) == 416
    kinds = Counter(
        "no summary"
        if not v.has_summary
        else "summary, no statistics"
        if "st" not in v.features
        else "summary with statistics"
        for v, _ in conformance.values()
    )
    assert kinds == {
        "summary with statistics": 220,
        "summary, no statistics": 172,
        "no summary": 24,
    }


def test_info_describes_every_valid_file(conformance):
    """Counts from the summary or from reading the file agree with what the file holds."""
    expected = {
        "NoData": (0, 0, 0, 0),
        "OneSchemalessMessage": (1, 1, 0, 0),
        "OneMessage": (1, 1, 0, 0),
        "OneAttachment": (0, 0, 1, 0),
        "OneMetadata": (0, 0, 0, 1),
        "TenMessages": (10, 1, 0, 0),
    }
    for name, (variant, path) in conformance.items():
        text = describe(path)
        messages, channels, attachments, metadata = expected[variant.input]
        assert "not an impactlab log" in text, name
        if messages:
            assert f", {messages} messages" in text, (name, text)
            assert f"  example  {messages:>8} msgs  " in text, (name, text)
        else:
            assert "duration:   - (no messages)" in text, (name, text)
        assert ("attachments: myFile" in text) == bool(attachments), (name, text)
        assert ("metadata:   myMetadata" in text) == bool(metadata), (name, text)
        # the summary alone suffices when it holds Statistics and a copy or index of every
        # channel, schema, attachment and metadata record
        has_schema = variant.input in ("OneMessage", "TenMessages")
        needed = {"st"} | {
            feature
            for feature, present in (
                ("rch", channels),
                ("rsh", has_schema),
                ("ax", attachments),
                ("mdx", metadata),
            )
            if present
        }
        assert ("counted by reading it" in text) == (not needed <= variant.features), name


def test_the_reader_answers_every_conformance_file(conformance):
    """analyze, diff and replay share this reader: all 416 files are not an impactlab log."""
    for name, (_, path) in conformance.items():
        with pytest.raises(LogError, match="not an impactlab log") as err:
            load_log(path)
        assert err.value.path == str(path), name


@pytest.mark.slow  # 36 commands, the analysis's workers started for each (over 10 s)
def test_every_command_answers_every_conformance_file(tmp_path, capsys, conformance):
    """analyze, diff and replay say in one line that a file is not an impactlab log (a sample
    of every input through each command line); info describes it."""
    sample = [
        p for n, (v, p) in conformance.items() if v.features in (frozenset(), {"ch", "mx", "pad"})
    ]
    assert len(sample) == 9  # every input; those with messages chunked and padded too
    for path in sample:
        for command, (argv, code) in COMMANDS.items():
            got, out, err = run_cli(capsys, argv(path, tmp_path))
            if command == "info":
                assert got == 0 and "not an impactlab log" in out
            else:
                assert got == code and "not an impactlab log" in error_line(err, path)


# ---------------------------------------------------------------------------------------------
# odd folders and outputs


@pytest.mark.slow
@pytest.mark.parametrize("command", ["analyze", "replay"])
def test_folders_without_logs(tmp_path, capsys, command, record_spec):
    """A folder named like a log, an empty folder, a pattern matching nothing: one line, exit 2,
    nothing written; among other inputs, one error line and exit 1, the others done."""
    (log,) = record_spec("limits", SMALL_SPEC)
    named = tmp_path / "x.mcap"
    named.mkdir()
    (named / "notes.txt").write_text("not a log")
    empty = tmp_path / "empty"
    empty.mkdir()
    argv = COMMANDS[command][0]
    for path, why in (
        (named, "a folder without .mcap logs"),
        (empty, "a folder without .mcap logs"),
        (tmp_path / "none-*.mcap", "matches no file"),
    ):
        code, _, err = run_cli(capsys, argv(path, tmp_path))
        assert code == 2 and error_line(err, path) == why
        assert not (tmp_path / "out").exists() and not (tmp_path / "rrd").exists()
    both = argv(named, tmp_path)
    both.insert(2, str(log))
    code, _, err = run_cli(capsys, both)
    assert code == 1 and error_line(err, named) == "a folder without .mcap logs"
    assert (tmp_path / "out" / "runs.parquet").exists() or (tmp_path / "rrd").is_dir()


def test_a_subfolder_named_like_a_log_is_searched_not_read(tmp_path, capsys, record_spec):
    (log,) = record_spec("limits", SMALL_SPEC)
    folder = tmp_path / "logs"
    (folder / "older.mcap").mkdir(parents=True)
    (folder / "older.mcap" / log.name).write_bytes(log.read_bytes())
    code, _, err = run_cli(capsys, ["replay", str(folder), "-o", str(tmp_path / "rrd")])
    assert code == 0, err
    assert [p.name for p in (tmp_path / "rrd").iterdir()] == [f"{log.stem}.rrd"]


def test_replay_into_a_file_that_is_not_a_recording(tmp_path, capsys, record_spec):
    (log,) = record_spec("limits", SMALL_SPEC)
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    code, _, err = run_cli(capsys, ["replay", str(log), "-o", str(notes)])
    assert code == 2 and "is a file, not a folder" in error_line(err, notes)
    assert notes.read_text() == "mine"
