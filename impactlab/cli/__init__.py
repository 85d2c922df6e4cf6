"""The `impactlab` command line: one module per command, each importing what it needs."""

from __future__ import annotations

import argparse
import errno
import gc
import os
import signal
import sys
import threading
from collections.abc import Sequence
from typing import Any, TextIO, cast

from impactlab.cli import (
    analyze,
    calibrate,
    contact,
    diff,
    examples,
    info,
    lab,
    record,
    replay,
)
from impactlab.cli.options import OneLineParser, started
from impactlab.errors import ImpactlabError
from impactlab.text import one_line
from impactlab.version import __version__

COMMANDS = (record, info, analyze, replay, diff, contact, calibrate, lab, examples)  # in help order


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    parser = OneLineParser(
        prog="impactlab",
        description="Simulated impact experiments: record MuJoCo runs to MCAP logs, analyze "
        "them, replay them in Rerun, compare them. `impactlab lab` does it all.",
    )
    parser.add_argument("--version", action="version", version=f"impactlab {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        command.register(sub)
    return parser


def _terminate(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # unwinds like Ctrl-C: partial files are removed on the way out


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code: a user mistake (`ImpactlabError`) is one
    line on stderr and its code (2 for a wrong option too), SIGTERM unwinds like Ctrl-C (130)."""
    args = build_parser().parse_args(argv)
    if not getattr(args, "gc_started_by_command", False):
        started()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _terminate)
    try:
        return int(args.func(args))
    except ImpactlabError as exc:
        print(one_line(f"impactlab: error: {exc}"), file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("impactlab: interrupted", file=sys.stderr)
        return 130


class StreamError(Exception):
    """Writing to stdout or stderr failed: a closed pipe, a full disk (not an `OSError`, so
    that no handler of file errors takes it for one of its own)."""

    def __init__(self, stream: str, fd: int, error: OSError) -> None:
        self.stream = stream
        self.fd = fd
        self.error = error
        super().__init__(f"{stream}: cannot write: {error.strerror or error}")


class GuardedStream:
    """A standard stream whose write errors raise `StreamError` (everything else passes)."""

    def __init__(self, name: str, stream: TextIO) -> None:
        self._name = name
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except OSError as exc:
            raise StreamError(self._name, self._stream.fileno(), exc) from None

    def flush(self) -> None:
        try:
            self._stream.flush()
        except OSError as exc:
            raise StreamError(self._name, self._stream.fileno(), exc) from None

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def _stream_failed(error: StreamError) -> int:
    """Drop what is still buffered for the broken stream; a line on stderr unless the pipe
    was closed (or stderr is the broken one). Returns the exit code."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, error.fd)  # the interpreter's last flush then writes nowhere, quietly
    os.close(devnull)
    if error.error.errno == errno.EPIPE:
        return 128 + signal.SIGPIPE
    if error.stream != "standard error":
        print(f"impactlab: error: {error}", file=sys.__stderr__)
    return 2


def _guarded_main() -> int:
    """`main` with stdout and stderr guarded and flushed before the interpreter exits: a closed
    pipe (`impactlab diff A B | head`) ends it silently, as it ends coreutils (141, 128 +
    SIGPIPE), a stream that cannot be written (`> /dev/full`) is one line and exit 2."""
    stdout, stderr = sys.stdout, sys.stderr
    sys.stdout = cast(TextIO, GuardedStream("standard output", stdout))
    sys.stderr = cast(TextIO, GuardedStream("standard error", stderr))
    try:
        try:
            code = main()
        except SystemExit as exc:  # argparse: --help, --version, a wrong option
            code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
        sys.stdout.flush()
        sys.stderr.flush()
        return code
    except StreamError as exc:
        return _stream_failed(exc)
    finally:
        sys.stdout, sys.stderr = stdout, stderr


def command() -> int:
    """The `impactlab` program (console script and `python -m impactlab`): `main` in a
    process of its own. No command renders with MuJoCo (replays are Rerun recordings), so
    MuJoCo's OpenGL back end is not loaded (`MUJOCO_GL=disable`, unless set): about 0.07 s
    less start-up for every command that simulates. The garbage collector is off until the
    command has started (`options.started`: `record` once it has planned, the others once
    their options are read): the imports and the planning make many objects and almost no
    garbage, and the collections would cost about a tenth of `impactlab record`'s start-up."""
    os.environ.setdefault("MUJOCO_GL", "disable")
    # the spec's schema uses no pydantic plugin: none is looked for in every installed
    # package's entry points (about 5 ms), unless set
    os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
    gc.disable()
    try:
        return _guarded_main()
    finally:
        started()
