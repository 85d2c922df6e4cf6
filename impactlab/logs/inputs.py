"""Which logs a command's inputs name: files, folders (searched recursively) and patterns."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from impactlab.errors import LogError


class NoLogs(LogError):
    """No input holds a log: a mistake in the command, nothing was done (exit code 2)."""

    exit_code = 2


def find_logs(
    inputs: Sequence[str | Path], *, empty: list[tuple[str, str]] | None = None
) -> list[Path]:
    """Expand files, folders (their *.mcap files, recursively) and glob patterns, sorted, unique.

    A folder named like a log (`x.mcap/`) is searched like any folder. Inputs that give no
    log are added to `empty` as (input, why), when it is given.
    """
    out: list[Path] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            found = sorted(p for p in path.rglob("*.mcap") if not p.is_dir())
            why = "a folder without .mcap logs"
        elif any(c in str(item) for c in "*?["):
            found = (
                sorted(Path().glob(str(item)))
                if not path.is_absolute()
                else sorted(Path(path.anchor).glob(str(path.relative_to(path.anchor))))
            )
            found = [p for p in found if not p.is_dir()]
            why = "matches no file"
        else:
            found, why = [path], ""
        if not found and empty is not None:
            empty.append((str(item), why))
        out += found
    return list(dict.fromkeys(out))


def require_logs(inputs: Sequence[str | Path]) -> tuple[list[Path], list[tuple[str, str]]]:
    """The logs the inputs name (`find_logs`), and the inputs that name none, with why.

    Raises:
        NoLogs: no input names a log (a folder without logs, a pattern matching nothing).
    """
    empty: list[tuple[str, str]] = []
    paths = find_logs(inputs, empty=empty)
    if not paths:
        if len(empty) == 1:
            raise NoLogs(*empty[0])
        raise NoLogs(" ".join(map(str, inputs)) or "(no input)", "none of these holds a log")
    return paths, empty
