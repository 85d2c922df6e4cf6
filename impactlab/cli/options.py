"""Options several commands share."""

from __future__ import annotations

import argparse
import gc
import math
from pathlib import Path

from impactlab.executors.base import PROCESS_MIN_ITEMS
from impactlab.executors.choose import EXECUTORS, RAY_INSTALL_HINT
from impactlab.text import one_line


def started() -> None:
    """The command has started (imported what it needs, planned its work): turn the garbage
    collector back on if the program turned it off (`impactlab.cli.command`), with the
    objects made so far frozen (kept for good, never scanned again: forked workers neither
    scan nor copy them)."""
    if not gc.isenabled():
        gc.freeze()
        gc.enable()


def add_executor_options(parser: argparse.ArgumentParser, default: str = "local") -> None:
    """Add `--executor` and `--address` to a subcommand's parser."""
    parser.add_argument(
        "--executor",
        choices=EXECUTORS,
        default=default,
        help="where tasks run: in this process (local), in one worker process per CPU of "
        f"this machine (processes; from {PROCESS_MIN_ITEMS} items) or on a Ray cluster (ray; needs "
        f"{RAY_INSTALL_HINT}); default: {default}",
    )
    parser.add_argument(
        "--address",
        metavar="ADDR",
        help="Ray cluster address HOST:PORT (default: start Ray on this machine); "
        "see docs/cluster.md",
    )


def path(text: str) -> Path:
    """An argument that names a file or folder: not empty (which would mean the working
    folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must not be empty (for this folder, give '.')")
    return Path(text)


def seconds(text: str) -> float:
    """An argument that is a duration in seconds: a finite number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number of seconds, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds > 0, got {text!r}")
    return value


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose mistakes are one line on stderr and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        line = one_line(f"{self.prog}: error: {message} (see {self.prog} --help)")
        self.exit(2, line + "\n")
