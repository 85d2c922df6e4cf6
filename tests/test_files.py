"""impactlab/files.py: inputs read only as bounded regular files; outputs under temporary names
that fit a file name, unique per call; output folders whose paths leave room for their files."""

from __future__ import annotations

import errno
import os
import socket
import threading
from pathlib import Path

import pytest

from impactlab.files import (
    DEEPEST_BYTES,
    NAME_MAX,
    OutputError,
    UnreadableInput,
    atomic_path,
    check_writable,
    is_text,
    read_regular,
    temporary_path,
    write_text,
)


def not_files(tmp_path: Path) -> dict[str, Path]:
    """What is not a regular file: each would make a plain read wait or never end."""
    os.mkfifo(tmp_path / "fifo")  # opening it to read waits for a writer: none will come
    (tmp_path / "zero").symlink_to("/dev/zero")
    (tmp_path / "link-to-fifo").symlink_to(tmp_path / "fifo")
    server = socket.socket(socket.AF_UNIX)
    server.bind(str(tmp_path / "socket"))
    return {
        "fifo": tmp_path / "fifo",
        "link to /dev/zero": tmp_path / "zero",
        "/dev/zero": Path("/dev/zero"),
        "/dev/urandom": Path("/dev/urandom"),
        "link to a fifo": tmp_path / "link-to-fifo",
        "socket": tmp_path / "socket",
    }


def test_what_is_not_a_regular_file_is_refused_without_waiting(tmp_path):
    for name, path in not_files(tmp_path).items():
        with pytest.raises(UnreadableInput) as caught:
            read_regular(path, 1000)
        assert str(caught.value) == "not a regular file (a device, pipe or socket)", name


def test_missing_folders_and_unreadable_files_are_the_systems_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_regular(tmp_path / "missing", 10)
    with pytest.raises(IsADirectoryError):
        read_regular(tmp_path, 10)
    (tmp_path / "dangling").symlink_to(tmp_path / "missing")
    with pytest.raises(FileNotFoundError):
        read_regular(tmp_path / "dangling", 10)


@pytest.mark.parametrize("size", [0, 1, 99, 100])
def test_files_up_to_the_limit_are_read_whole(tmp_path, size):
    path = tmp_path / "f"
    path.write_bytes(bytes(range(256))[:size] * 1)
    assert read_regular(path, 100) == path.read_bytes()


@pytest.mark.parametrize("size", [101, 10**6, 1 << 40])
def test_files_over_the_limit_are_refused_after_reading_one_byte_more(tmp_path, size):
    """A sparse file of a terabyte costs a read of 101 bytes, not its size."""
    path = tmp_path / "f"
    with open(path, "wb") as stream:
        stream.truncate(size)
    with pytest.raises(UnreadableInput) as caught:
        read_regular(path, 100)
    assert caught.value.errno == errno.EFBIG and str(caught.value) == "larger than 100 bytes"


def name_of(length: int, char: str = "x") -> str:
    """A name of `length` bytes of UTF-8 text made of `char` (1 to 4 bytes each), then `x`s."""
    size = len(char.encode())
    return char * (length // size) + "x" * (length % size)


@pytest.mark.parametrize("char", ["x", "é", "€", "🎯"])
@pytest.mark.parametrize("length", [1, 200, 230, 243, 244, 250, 254, 255])
def test_temporary_names_fit_a_file_name_and_stay_text(tmp_path, char, length):
    """Whatever a name's length up to NAME_MAX bytes and its characters' widths, its temporary
    name beside it fits NAME_MAX bytes, is cut only between characters, and can be written."""
    path = tmp_path / name_of(length, char)
    assert len(os.fsencode(path.name)) == length
    tmp = temporary_path(path)
    assert tmp.parent == path.parent and tmp.name.startswith(".")
    assert len(os.fsencode(tmp.name)) <= NAME_MAX and is_text(tmp)
    assert write_text(path, "whole").read_text() == "whole"
    assert [p.name for p in tmp_path.iterdir()] == [path.name]


def test_temporary_names_of_names_that_are_not_text(tmp_path):
    path = tmp_path / os.fsdecode(b"caf\xe9-" + b"\xff" * 249)
    assert len(os.fsencode(path.name)) == 254 and not is_text(path)
    assert len(os.fsencode(temporary_path(path).name)) <= NAME_MAX
    assert write_text(path, "whole").read_text() == "whole"


def test_temporary_names_are_unique_to_each_call_in_every_thread(tmp_path):
    """Threads writing one file at once each write their own temporary file: the file ends
    whole, as one of them wrote it."""
    path = tmp_path / "shared.txt"
    names: list[Path] = []
    start = threading.Barrier(8)

    def write(i: int) -> None:
        start.wait()
        for _ in range(50):
            with atomic_path(path) as tmp:
                names.append(tmp)
                tmp.write_text(f"{i}\n" * 1000)

    threads = [threading.Thread(target=write, args=(i,)) for i in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(set(names)) == len(names) == 400
    lines = path.read_text().splitlines()
    assert len(lines) == 1000 and len(set(lines)) == 1
    assert [p.name for p in tmp_path.iterdir()] == ["shared.txt"]


def deep_folder(tmp_path: Path, length: int) -> Path:
    """A folder below `tmp_path` whose absolute path is `length` bytes (not made)."""
    parts, left = [], length - len(os.fsencode(str(tmp_path)))
    while left > 0:
        part = min(200, left - 1)
        parts.append("d" * part)
        left -= part + 1
    folder = tmp_path.joinpath(*parts)
    assert len(os.fsencode(str(folder))) == length
    return folder


def test_output_folders_near_path_max_are_refused_naming_the_folder(tmp_path):
    """An output folder whose path leaves less than DEEPEST_BYTES under PATH_MAX is refused
    before anything is made, naming the folder and its length; one byte shorter is made."""
    path_max = os.pathconf("/", "PC_PATH_MAX")
    longest = path_max - 1 - DEEPEST_BYTES
    for length in (longest + 1, longest + 100, path_max - 1, path_max + 10):
        folder = deep_folder(tmp_path, length)
        with pytest.raises(OutputError) as caught:
            check_writable(folder)
        assert caught.value.path == str(folder)
        assert f"too long: {length:,} bytes" in caught.value.problem
        assert not any(tmp_path.iterdir())
    folder = deep_folder(tmp_path, longest)
    check_writable(folder)
    deepest = folder / ".impactlab-staging-12345678" / "figures" / ("n" * NAME_MAX)
    deepest.parent.mkdir(parents=True)
    write_text(deepest, "the deepest file impactlab writes there fits")


def test_relative_output_folders_are_measured_as_absolute_paths(tmp_path, monkeypatch):
    folder = deep_folder(tmp_path, os.pathconf("/", "PC_PATH_MAX") - DEEPEST_BYTES)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(OutputError, match="too long"):
        check_writable(folder.relative_to(tmp_path))
