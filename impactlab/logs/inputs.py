"""Which logs a command's inputs name: files, folders (searched recursively) and patterns."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Sequence
from pathlib import Path

from impactlab.errors import LogError
from impactlab.files import NOT_TEXT, UnreadableInput, is_text, open_regular

MAGIC = b"\x89MCAP0\r\n"  # every MCAP file starts with it


class NoLogs(LogError):
    """No input holds a log: a mistake in the command, nothing was done (exit code 2)."""

    exit_code = 2


def find_logs(
    inputs: Sequence[str | Path], *, empty: list[tuple[str, str]] | None = None
) -> list[Path]:
    """Expand files, folders (their *.mcap files, recursively) and glob patterns, sorted, unique.

    A name is what it names: an existing file or folder is taken as it is written, even with
    `*`, `?` or `[` in it; only a name that does not exist is a pattern (as a shell does,
    its leading folders that exist taken as written too). A folder named like a log
    (`x.mcap/`) is searched like any folder. Inputs that give no log are added to `empty` as
    (input, why), when it is given; with `text`, so are logs whose name is not UTF-8 text.
    """
    return [Path(name) for name in log_names(inputs, empty=empty)]


def log_names(
    inputs: Sequence[str | Path],
    *,
    empty: list[tuple[str, str]] | None = None,
    text: bool = False,
) -> list[str]:
    """`find_logs` as strings (each `str` of the Path, in the same order): a Path holds its
    parts besides its text, about 0.4 KB per log that a sweep of 100,000 logs would keep."""
    out: list[str] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            found = sorted((str(p) for p in path.rglob("*.mcap") if not p.is_dir()), key=_parts)
            why = "a folder without .mcap logs"
        elif not os.path.lexists(path) and any(c in str(item) for c in "*?["):
            found = sorted((str(p) for p in _matches(path) if not p.is_dir()), key=_parts)
            why = "matches no file"
        else:
            found, why = [str(path)], ""
        if text and not all(map(is_text, found)):
            named = [name for name in found if is_text(name)]
            if empty is not None:
                empty.append((str(item), f"{len(found) - len(named)} log(s): {NOT_TEXT}"))
            found, why = named, ""
        if not found and why and empty is not None:
            empty.append((str(item), why))
        out += found
    return list(dict.fromkeys(out))


def _matches(pattern: Path) -> Iterator[Path]:
    """What a pattern matches, its leading folders that exist taken as they are written."""
    parts = pattern.parts
    start = 1 if pattern.is_absolute() else 0  # parts[0] is then the root
    while start < len(parts) - 1 and Path(*parts[: start + 1]).is_dir():
        start += 1
    return Path(*parts[:start]).glob(str(Path(*parts[start:])))


def _parts(name: str) -> list[str]:
    """The sort key of a path's text: its parts, as Paths are ordered (`a/b` before `a-c`)."""
    return name.split(os.sep)


def require_logs(inputs: Sequence[str | Path]) -> tuple[list[Path], list[tuple[str, str]]]:
    """The logs the inputs name (`find_logs`), and the inputs that name none, with why.

    Raises:
        NoLogs: no input names a log (a folder without logs, a pattern matching nothing).
    """
    names, empty = require_log_names(inputs)
    return [Path(name) for name in names], empty


def require_log_names(
    inputs: Sequence[str | Path], *, text: bool = False
) -> tuple[list[str], list[tuple[str, str]]]:
    """`require_logs` as strings (`log_names`, `text` as there).

    Raises:
        NoLogs: no input names a log (`check_log_inputs`).
    """
    check_log_inputs(inputs)
    empty: list[tuple[str, str]] = []
    paths = log_names(inputs, empty=empty, text=text)
    if not paths:
        if len(empty) == 1:
            raise NoLogs(*empty[0])
        raise NoLogs(" ".join(map(str, inputs)) or "(no input)", "none of these holds a log")
    return paths, empty


def check_log_inputs(inputs: Sequence[str | Path]) -> None:
    """At least one input is a file that starts as an MCAP file does, or a folder or pattern
    that finds a log. Otherwise the command can do nothing: a mistake in it (exit 2), said
    before any output is created. Among inputs that work, a bad one is the job's error line
    (exit 1), and the others are done.

    Raises:
        NoLogs: no input names a log; the message names the first input and its problem.
    """
    problems = [input_problem(Path(item)) for item in inputs]
    if problems and problems[0] is not None and all(problems):
        raise NoLogs(*problems[0])


def input_problem(path: Path) -> tuple[str, str] | None:
    """What is wrong with one input, (input, problem), or None when it names a log: a file
    that starts as an MCAP file does, or a folder or pattern that finds one."""
    if path.is_dir() or (not path.exists() and any(c in str(path) for c in "*?[")):
        empty: list[tuple[str, str]] = []  # a folder or pattern: does it find a log?
        return None if log_names([path], empty=empty) else empty[0]
    try:
        with log_errors(path), open_regular(path) as stream:  # never waits: a pipe is refused
            magic = stream.read(len(MAGIC))
    except LogError as exc:
        return exc.path, exc.problem
    if magic != MAGIC:
        spec = path.suffix in (".toml", ".xml")
        hint = "; `impactlab record` records a spec or model" if spec else ""
        return str(path), f"not an MCAP file (bad magic bytes){hint}"
    return None


@contextlib.contextmanager
def log_errors(path: str | os.PathLike[str]) -> Iterator[None]:
    """Failures to read `path` as LogError, one sentence each (missing, a folder, not a
    regular file, unreadable, too large or not MCAP)."""
    try:
        yield
    except FileNotFoundError:
        raise LogError(str(path), "file not found") from None
    except IsADirectoryError:
        raise LogError(str(path), "is a folder, not a log") from None
    except UnreadableInput as exc:
        raise LogError(str(path), f"{exc}: not a log") from None
    except OSError as exc:
        raise LogError(str(path), f"cannot read: {exc.strerror or exc}") from None
    except ValueError as exc:  # not a regular file, too large, not MCAP
        raise LogError(str(path), str(exc)) from None
