"""Spec files that are not files: a pipe, a device, a link to one, a socket, a folder, a file
larger than a spec can be; each is one line naming it, exit 2, read without waiting and
within the size limit (a spec of /dev/zero would otherwise fill the memory)."""

from __future__ import annotations

import os
import signal
import socket
from pathlib import Path

import pytest
from specs import drop, toml

from impactlab.cli import main
from impactlab.record.spec import MAX_SPEC_BYTES


@pytest.fixture
def guard():
    """Stop a read that waits (the bug this file tests for) instead of hanging the suite."""

    def stop(signum, frame):
        raise TimeoutError("the spec's read waited")

    previous = signal.signal(signal.SIGALRM, stop)
    signal.alarm(60)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def refused(capsys, spec: Path | str, out: Path) -> str:
    """Record `spec`: exit 2, nothing written, one error line; returns what it says of it."""
    code = main(["record", str(spec), "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert not out.exists()
    prefix = f"impactlab: error: {spec}: "
    assert err[0].startswith(prefix), err
    return err[0].removeprefix(prefix)


def test_specs_that_are_not_regular_files(tmp_path, capsys, guard):
    os.mkfifo(tmp_path / "fifo.toml")
    (tmp_path / "zero.toml").symlink_to("/dev/zero")
    (tmp_path / "fifo-link.toml").symlink_to(tmp_path / "fifo.toml")
    server = socket.socket(socket.AF_UNIX)
    server.bind(str(tmp_path / "socket.toml"))
    for name in ("fifo.toml", "zero.toml", "fifo-link.toml", "socket.toml"):
        said = refused(capsys, tmp_path / name, tmp_path / "logs")
        assert said == "cannot read: not a regular file (a device, pipe or socket)", name
    (tmp_path / "folder.toml").mkdir()
    assert "cannot read" in refused(capsys, tmp_path / "folder.toml", tmp_path / "logs")
    server.close()


@pytest.mark.parametrize("extra", [1, 1 << 30, 1 << 40])
def test_specs_over_the_limit_are_refused_reading_one_byte_more(tmp_path, capsys, extra):
    """Sparse files of up to a terabyte: refused after MAX_SPEC_BYTES + 1 bytes are read."""
    spec = tmp_path / "big.toml"
    with open(spec, "wb") as stream:
        stream.truncate(MAX_SPEC_BYTES + extra)
    said = refused(capsys, spec, tmp_path / "logs")
    assert said == f"cannot read: larger than {MAX_SPEC_BYTES:,} bytes"


def test_a_spec_of_the_largest_size_is_read(tmp_path, capsys):
    """A spec padded with a comment to exactly MAX_SPEC_BYTES is read and recorded."""
    text = toml(drop("padded", max_time=0.01))
    spec = tmp_path / "padded.toml"
    spec.write_text(text + "#" * (MAX_SPEC_BYTES - len(text.encode()) - 1) + "\n")
    assert spec.stat().st_size == MAX_SPEC_BYTES
    assert main(["record", str(spec), "-o", str(tmp_path / "logs")]) == 0
    assert len(list((tmp_path / "logs").glob("*.mcap"))) == 1
    capsys.readouterr()
