"""Options several commands share."""

from __future__ import annotations

import argparse

from impactlab.executors.choose import EXECUTORS, RAY_INSTALL_HINT


def add_executor_options(parser: argparse.ArgumentParser) -> None:
    """Add `--executor` and `--address` to a subcommand's parser."""
    parser.add_argument(
        "--executor",
        choices=EXECUTORS,
        default="local",
        help="where tasks run: this machine (local, the default) or a Ray cluster (ray; "
        f"needs {RAY_INSTALL_HINT})",
    )
    parser.add_argument(
        "--address",
        metavar="ADDR",
        help="Ray cluster address HOST:PORT (default: start Ray on this machine); "
        "see docs/cluster.md",
    )


def make_executor(args: argparse.Namespace):
    """The executor the options ask for (checked before any work is done)."""
    from impactlab.executors.choose import make_executor as make

    return make(args.executor, args.address)
