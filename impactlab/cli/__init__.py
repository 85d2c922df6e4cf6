"""The `impactlab` command line: a thin layer over the Python API, one module per command.

Building the parser imports no heavy library (MuJoCo, polars, matplotlib, rerun): each
command imports what it needs when it runs. User mistakes (`ImpactlabError`) become one
line on stderr and a non-zero exit code, and so do wrong options (exit 2); SIGTERM unwinds
like Ctrl-C (exit 130).

The program (`command`) starts with Python's cyclic garbage collector off: the imports and
the planning make many objects and almost no garbage, and the collections they would trigger
cost about a tenth of `impactlab record`'s start-up. `record` turns it back on once it has
planned (`impactlab.cli.options.started`), every other command as soon as its options are read.
"""

from __future__ import annotations

import argparse
import gc
import os
import signal
import sys
import threading
from collections.abc import Sequence

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
from impactlab.text import terminal_text
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
    """Run the command line; returns the exit code."""
    args = build_parser().parse_args(argv)
    if not getattr(args, "gc_started_by_command", False):
        started()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _terminate)
    try:
        return int(args.func(args))
    except ImpactlabError as exc:
        print(terminal_text(f"impactlab: error: {exc}"), file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("impactlab: interrupted", file=sys.stderr)
        return 130


def command() -> int:
    """The `impactlab` program (console script and `python -m impactlab`): `main` in a
    process of its own. No command renders with MuJoCo (replays are Rerun recordings), so
    MuJoCo's OpenGL back end is not loaded (`MUJOCO_GL=disable`, unless set): about 0.07 s
    less start-up for every command that simulates. The garbage collector is off until the
    command has started (see the module's docstring)."""
    os.environ.setdefault("MUJOCO_GL", "disable")
    # the spec's schema uses no pydantic plugin: none is looked for in every installed
    # package's entry points (about 5 ms), unless set
    os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
    gc.disable()
    try:
        return main()
    finally:
        started()
