"""The errors impactlab raises for user mistakes and unreadable input.

The command line turns each into one line on stderr and a non-zero exit code, with no
traceback. Anything else that escapes is a bug.
"""

from __future__ import annotations


class ImpactlabError(Exception):
    """Base class of every error caused by the user's input rather than by impactlab."""

    exit_code = 2


class SpecError(ImpactlabError):
    """An experiment spec, an override or an MJCF file is wrong.

    The message names the file, the field and the problem: ``drop.toml: bodies.ball.radius:
    must be > 0, got -0.1``.
    """

    def __init__(self, source: str, field: str, problem: str) -> None:
        self.source = source
        self.field = field
        self.problem = problem
        where = f"{source}: {field}" if field else source
        super().__init__(f"{where}: {problem}")


class LogError(ImpactlabError):
    """A log file cannot be read (not MCAP, truncated, not written by impactlab)."""

    exit_code = 1

    def __init__(self, path: str, problem: str) -> None:
        self.path = path
        self.problem = problem
        super().__init__(f"{path}: {problem}")
