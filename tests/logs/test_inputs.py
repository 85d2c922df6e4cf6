"""Which logs a command's inputs name: the names as text, in the order Paths sort in."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from impactlab.logs.inputs import NoLogs, find_logs, log_names, require_log_names


@pytest.fixture
def tree(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Logs whose text order differs from their path order (`a-c/` sorts before `a/` as
    text, after it as parts), a folder named like a log, and a file that is not a log."""
    for name in ("a/b.mcap", "a-c/x.mcap", "a/z/y.mcap", "A/q.mcap", "dir.mcap/in.mcap", "a/n.txt"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_bytes(b"")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_a_folder_gives_its_logs_in_path_order(tree):
    expected = sorted(p for p in tree.rglob("*.mcap") if not p.is_dir())
    assert log_names([tree]) == [str(p) for p in expected]
    assert find_logs([tree]) == expected
    assert [n.split(os.sep)[-2:] for n in log_names(["."])][:3] == [
        ["A", "q.mcap"],
        ["a", "b.mcap"],
        ["z", "y.mcap"],
    ]


def test_patterns_files_and_repeats(tree):
    """A relative and an absolute pattern, a file named twice: sorted within each input,
    each log once, in the order of the inputs."""
    names = log_names(["a*/*.mcap", str(tree / "a" / "b.mcap"), "A/q.mcap", "a/b.mcap"])
    assert names == [str(Path(n)) for n in ("a/b.mcap", "a-c/x.mcap")] + [
        str(tree / "a" / "b.mcap"),
        "A/q.mcap",
    ]
    absolute = log_names([str(tree / "a" / "**" / "*.mcap")])
    assert absolute == [str(tree / "a" / "b.mcap"), str(tree / "a" / "z" / "y.mcap")]


def test_inputs_without_logs_are_named_with_why(tree):
    empty: list[tuple[str, str]] = []
    assert log_names(["a/z", "nothing*.mcap"], empty=empty) == ["a/z/y.mcap"]
    assert empty == [("nothing*.mcap", "matches no file")]
    with pytest.raises(NoLogs) as caught:
        require_log_names(["nothing*.mcap"])
    assert caught.value.problem == "matches no file"
