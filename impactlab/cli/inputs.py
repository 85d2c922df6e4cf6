"""The logs a command names, checked before it creates anything (none readable: exit 2)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from impactlab.files import UnreadableInput, open_regular
from impactlab.logs.inputs import NoLogs, require_log_names

MAGIC = b"\x89MCAP0\r\n"  # every MCAP file starts with it (impactlab.logs.reader.MAGIC)


def check_log_inputs(inputs: Sequence[str | Path]) -> None:
    """At least one input is a file that starts as an MCAP file does, or a folder or pattern
    that finds a log. Otherwise the command can do nothing: a mistake in it (exit 2), said
    before any output is created. Among inputs that work, a bad one is the job's error line
    (exit 1), and the others are done.

    Raises:
        NoLogs: no input names a log; the message names the first input and its problem.
    """
    problems = [_problem(Path(item)) for item in inputs]
    if problems and problems[0] is not None and all(problems):
        raise NoLogs(*problems[0])


def _problem(path: Path) -> tuple[str, str] | None:
    """What is wrong with one input, or None when it names a log."""
    if path.is_dir() or (not path.exists() and any(c in str(path) for c in "*?[")):
        try:
            require_log_names([path])  # a folder or pattern: does it find a log?
        except NoLogs as exc:
            return exc.path, exc.problem
        return None
    try:
        with open_regular(path) as stream:  # never waits: a pipe is refused
            magic = stream.read(len(MAGIC))
    except FileNotFoundError:
        return str(path), "file not found"
    except UnreadableInput as exc:
        return str(path), f"{exc}: not a log"
    except OSError as exc:
        return str(path), f"cannot read: {exc.strerror or exc}"
    if magic != MAGIC:
        spec = path.suffix in (".toml", ".xml")
        hint = "; `impactlab record` records a spec or model" if spec else ""
        return str(path), f"not an MCAP file (bad magic bytes){hint}"
    return None
