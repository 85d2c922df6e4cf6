"""Publishing an analysis: it removes only files it wrote in the output folder, reached without
following a link; the folder's manifest is untrusted input, as a log is."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest
from specs import drop, toml

from impactlab.analyze import publish as publish_module
from impactlab.analyze.publish import LOCK, MANIFEST, publish, read_manifest, staged
from impactlab.cli import main
from impactlab.files import OutputError


def analysis(out: Path, files: dict[str, str]) -> list[Path]:
    """Publish `files` (relative name -> text) into `out` as an analysis does."""
    out.mkdir(exist_ok=True)
    with staged(out) as stage:
        written = []
        for name, text in files.items():
            (stage / name).parent.mkdir(parents=True, exist_ok=True)
            (stage / name).write_text(text)
            written.append(stage / name)
        return publish(stage, out, written)


def identity(path: Path) -> list[int]:
    info = path.stat()
    return [info.st_ino, info.st_size, info.st_mtime_ns]


def snapshot(folder: Path) -> dict[str, str]:
    """Every file below `folder` (links not followed) with its text, and every link's target;
    not impactlab's bookkeeping (the manifest, the lock)."""
    out = {}
    for path in sorted(folder.rglob("*")):
        name = path.relative_to(folder).as_posix()
        if path.name.startswith(".impactlab-"):
            continue
        if path.is_symlink():
            out[name] = f"-> {os.readlink(path)}"
        elif path.is_file():
            out[name] = path.read_text(errors="replace")
    return out


def forge(out: Path, entries: dict[str, list[list[int]]]) -> None:
    (out / MANIFEST).write_text(json.dumps({"files": entries}))


def test_a_new_analysis_removes_what_the_last_one_wrote_and_no_longer_writes(tmp_path):
    out = tmp_path / "results"
    analysis(out, {"report.md": "1", "figures/a.png": "a", "figures/deep/b.png": "b"})
    (out / "notes.md").write_text("mine")
    analysis(out, {"report.md": "2"})
    assert snapshot(out) == {"report.md": "2", "notes.md": "mine"}  # empty folders go too
    assert set(read_manifest(out)) == {"report.md"}


def test_a_file_impactlab_wrote_that_the_user_changed_is_kept(tmp_path):
    out = tmp_path / "results"
    analysis(out, {"report.md": "1", "figures/a.png": "a"})
    (out / "figures" / "a.png").write_text("edited by the user, now theirs")
    analysis(out, {"report.md": "2"})
    assert (out / "figures" / "a.png").read_text() == "edited by the user, now theirs"


def test_a_manifest_from_elsewhere_removes_nothing(tmp_path):
    """A received folder whose manifest lists the user's files, the log in it and files
    through a link, with their names, sizes and times right (a forger knows them) and only
    the inode guessed: the analysis removes none of them."""
    out = tmp_path / "recv"
    elsewhere = tmp_path / "elsewhere"
    (out / "figures").mkdir(parents=True)
    elsewhere.mkdir()
    for path, text in {
        out / "run.mcap": "the log",
        out / "notes.md": "mine",
        out / "figures" / "mine.png": "mine too",
        elsewhere / "data.txt": "precious",
    }.items():
        path.write_text(text)
    (out / "link").symlink_to(elsewhere)
    (out / "figures" / "link").symlink_to(elsewhere)
    (out / "data.txt").symlink_to(elsewhere / "data.txt")

    def guessed(path: Path) -> list[list[int]]:
        ino, size, mtime = identity(path)
        return [[ino + d, size, mtime] for d in (-2, -1, 1, 2)] + [[0, size, mtime]]

    names = ["run.mcap", "notes.md", "figures/mine.png"]
    entries = {name: guessed(out / name) for name in names}
    # through a link, even with the target's own identity: never followed
    entries["link/data.txt"] = [identity(elsewhere / "data.txt")]
    entries["figures/link/data.txt"] = [identity(elsewhere / "data.txt")]
    entries["data.txt"] = [identity(elsewhere / "data.txt")]  # a link at the name itself
    before = snapshot(tmp_path)
    forge(out, entries)
    analysis(out, {"report.md": "r"})
    after = snapshot(tmp_path)
    assert after.pop("recv/report.md") == "r"
    assert after == before


@pytest.mark.parametrize(
    "document",
    [
        {"files": ["report.md", "notes.md"]},  # the earlier format: names without identities
        {"files": {"/etc/passwd": [[1, 2, 3]], "../victim": [[1, 2, 3]], "a/../../v": []}},
        {"files": {"": [[1, 2, 3]], ".": [[1, 2, 3]], "./": [], "a\0b": [], "a\\b": []}},
        {"files": {"notes.md": [[True, True, True]], "x": "y", "z": [[1, 2]], "w": [None]}},
        {"files": {"notes.md": [[1.0, 2.0, 3.0]], "v": [["1", "2", "3"]]}},
        {"files": 7},
        {"files": None},
        [1, 2, 3],
        "a string",
        None,
        {"no files": {}},
    ],
    ids=repr,
)
def test_odd_manifests_are_ignored(tmp_path, document):
    out = tmp_path / "results"
    out.mkdir()
    (out / "notes.md").write_text("mine")
    (tmp_path / "victim").write_text("keep")
    (out / MANIFEST).write_text(json.dumps(document))
    analysis(out, {"report.md": "r"})
    assert (out / "notes.md").read_text() == "mine" and (tmp_path / "victim").read_text() == "keep"
    assert set(read_manifest(out)) == {"report.md"}


@pytest.mark.parametrize("kind", ["fifo", "link to /dev/zero", "folder", "huge", "deep"])
def test_manifests_that_are_not_files_are_read_within_bounds(tmp_path, kind, monkeypatch):
    """A manifest that is a pipe, a device, a folder, larger than its limit or nested beyond
    the parser's depth: read without waiting or filling the memory, and ignored."""
    out = tmp_path / "results"
    out.mkdir()
    manifest = out / MANIFEST
    if kind == "fifo":
        os.mkfifo(manifest)  # opening it to read would wait for a writer
    elif kind == "link to /dev/zero":
        manifest.symlink_to("/dev/zero")
    elif kind == "folder":
        manifest.mkdir()
    elif kind == "huge":
        monkeypatch.setattr(publish_module, "MAX_MANIFEST_BYTES", 100)
        manifest.write_text(json.dumps({"files": {"x" * 200: [[1, 2, 3]]}}))
    else:
        manifest.write_text("[" * 100_000 + "]" * 100_000)
    assert read_manifest(out) == {}
    monkeypatch.undo()
    if kind != "folder":  # a folder in the manifest's way: publishing cannot write it
        analysis(out, {"report.md": "r"})
        assert set(read_manifest(out)) == {"report.md"}


def test_a_manifest_that_is_a_link_is_replaced_not_written_through(tmp_path):
    out = tmp_path / "results"
    out.mkdir()
    mine = tmp_path / "mine.json"
    mine.write_text("{}")
    (out / MANIFEST).symlink_to(mine)
    analysis(out, {"report.md": "r"})
    assert mine.read_text() == "{}"
    assert not (out / MANIFEST).is_symlink() and set(read_manifest(out)) == {"report.md"}


@pytest.mark.parametrize("target", ["missing", "file"])
def test_a_lock_that_is_a_link_is_refused(tmp_path, target):
    """A lock file that is a link (dangling or to a file) is neither created nor written
    through: one error naming it, nothing published."""
    out = tmp_path / "results"
    out.mkdir()
    outside = tmp_path / "outside"
    if target == "file":
        outside.write_text("keep")
    (out / LOCK).symlink_to(outside)
    with pytest.raises(OutputError, match="a link, not impactlab's lock file"):
        analysis(out, {"report.md": "r"})
    assert not (out / "report.md").exists()
    assert (outside.read_text() == "keep") if target == "file" else not outside.exists()


@pytest.mark.parametrize("way", ["link", "file"])
def test_a_link_or_file_in_the_way_of_a_folder_is_refused_before_anything_moves(tmp_path, way):
    out = tmp_path / "results"
    analysis(out, {"report.md": "1", "figures/a.png": "a"})
    elsewhere = tmp_path / "elsewhere"
    shutil.move(out / "figures", elsewhere)  # the figures, where a link now points
    if way == "link":
        (out / "figures").symlink_to(elsewhere)
    else:
        (out / "figures").write_text("a file named figures")
    before = snapshot(tmp_path)
    with pytest.raises(OutputError, match="figures: cannot write there: a link or a file"):
        analysis(out, {"report.md": "2", "figures/b.png": "b"})
    assert snapshot(tmp_path) == before
    # an analysis writing no figure removes none through the link either: the old figure,
    # moved out, is listed with its identity but never reached
    analysis(out, {"report.md": "3"})
    assert (elsewhere / "a.png").read_text() == "a"


@pytest.fixture(scope="module")
def logs(record_spec) -> list[Path]:
    spec = drop("publish", z=0.3, max_time=0.4, sweep={"ball.mass": [1.0, 2.0]})
    return record_spec("publish", toml(spec))


@pytest.mark.slow
def test_analyzing_a_received_folder_into_itself(tmp_path, logs, capsys):
    """The issue's case: `impactlab analyze recv -o recv`, where recv came with a manifest
    listing the user's notes, the log and a file through a link. All stay; a second
    analysis with one log fewer removes that log's figure, which this machine wrote."""
    recv = tmp_path / "recv"
    recv.mkdir()
    for log in logs:
        shutil.copy2(log, recv / log.name)
    (recv / "notes.md").write_text("mine")
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "data.txt").write_text("precious")
    (recv / "link").symlink_to(tmp_path / "elsewhere")
    listed = ["notes.md", *(log.name for log in logs), "link/data.txt"]
    forge(recv, {name: [[*identity(recv / name)[:2], 0]] for name in listed})  # made elsewhere
    before = snapshot(tmp_path)
    assert main(["analyze", str(recv), "-o", str(recv)]) == 0
    after = snapshot(tmp_path)
    assert {k: after[k] for k in before} == before
    figure = f"recv/figures/energy-{logs[1].stem}.png"
    assert figure in after
    assert main(["analyze", str(recv / logs[0].name), "-o", str(recv)]) == 0
    again = snapshot(tmp_path)
    assert figure not in again
    assert {k: again[k] for k in before} == before
    capsys.readouterr()
