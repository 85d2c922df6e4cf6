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


@pytest.fixture
def odd(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Logs whose names are also patterns (`run[1]`, `*`, `?`, `[!x]`), beside the logs those
    patterns match, and a folder named like a pattern beside the folder it matches."""
    for name in (
        "run[1].mcap",
        "run1.mcap",
        "*.mcap",
        "a?.mcap",
        "ab.mcap",
        "[!x].mcap",
        "y.mcap",
        "exp[1]/in.mcap",
        "exp1/other.mcap",
    ):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_bytes(b"")
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize("name", ["run[1].mcap", "*.mcap", "a?.mcap", "[!x].mcap"])
def test_a_name_that_exists_is_taken_as_written(odd, name):
    """A log whose name holds glob characters is that log, relative or absolute, never the
    logs its name would match as a pattern."""
    assert log_names([name]) == [name]
    assert log_names([str(odd / name)]) == [str(odd / name)]


def test_a_folder_whose_name_is_a_pattern_is_that_folder(odd):
    assert log_names(["exp[1]"]) == [str(Path("exp[1]/in.mcap"))]
    assert log_names(["exp[1]/*.mcap"]) == [str(Path("exp[1]/in.mcap"))]
    assert log_names([str(odd / "exp[1]" / "*.mcap")]) == [str(odd / "exp[1]" / "in.mcap")]


def test_a_name_that_does_not_exist_is_a_pattern(odd):
    """Only then, as a shell does: `run[2].mcap` matches nothing, `r*[1].mcap` both logs,
    a pattern in a folder's name every folder it matches (`exp?` is not a folder)."""
    empty: list[tuple[str, str]] = []
    assert log_names(["run[2].mcap"], empty=empty) == []
    assert empty == [("run[2].mcap", "matches no file")]
    assert log_names(["r*[1].mcap"]) == ["run1.mcap"]  # `run[1].mcap` has no `1` before `.`
    assert log_names(["exp?/*.mcap"]) == [str(Path("exp1/other.mcap"))]
    assert log_names(["e*/*.mcap"]) == [str(Path(p)) for p in ("exp1/other.mcap", "exp[1]/in.mcap")]


def test_names_that_are_not_text_are_named_with_why(tmp_path, monkeypatch):
    """With `text` (analyze: names go into tables), a log, a folder of logs or a pattern whose
    matches have names that are not UTF-8 text is one (input, why), the others kept."""
    bad = os.fsdecode(b"caf\xe9")
    for name in (f"{bad}.mcap", f"{bad}/a.mcap", "mixed/ok.mcap", f"mixed/{bad}.mcap"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_bytes(b"")
    monkeypatch.chdir(tmp_path)
    inputs = [f"{bad}.mcap", bad, "mixed", "m*/*.mcap"]
    assert log_names(inputs) == [
        f"{bad}.mcap",
        f"{bad}/a.mcap",
        f"mixed/{bad}.mcap",
        "mixed/ok.mcap",
    ]
    empty: list[tuple[str, str]] = []
    assert log_names(inputs, empty=empty, text=True) == ["mixed/ok.mcap"]
    assert [(where, why.split(":")[0]) for where, why in empty] == [
        (f"{bad}.mcap", "1 log(s)"),
        (bad, "1 log(s)"),
        ("mixed", "1 log(s)"),
        ("m*/*.mcap", "1 log(s)"),
    ]
    assert all(
        why.endswith("not UTF-8 text, which tables, reports and logs hold: rename it")
        for _, why in empty
    )
    with pytest.raises(NoLogs, match="not UTF-8 text"):
        require_log_names([bad], text=True)
