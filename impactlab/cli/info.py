"""`impactlab info LOG...`: what logs hold."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the `info` subcommand."""
    info = sub.add_parser("info", help="print what logs hold (run, outcome, channels)")
    info.add_argument("logs", nargs="+", type=Path, metavar="LOG", help="logs, folders or globs")
    info.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Describe each log; one error line per log that cannot be read (exit 1); none that can:
    one line, exit 2."""
    from impactlab.errors import ImpactlabError
    from impactlab.logs.inputs import require_logs
    from impactlab.text import one_line, terminal_text
    from impactlab.tools.info import describe

    paths, empty = require_logs(args.logs)  # none names a log: NoLogs, exit 2
    for where, why in empty:
        print(one_line(f"impactlab: error: {where}: {why}"), file=sys.stderr)
    failed = len(empty)
    for i, path in enumerate(paths):
        try:
            text = describe(path)
        except ImpactlabError as exc:
            print(one_line(f"impactlab: error: {exc}"), file=sys.stderr)
            failed += 1
            continue
        print(terminal_text(("\n" if i else "") + text))
    return 1 if failed else 0
