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
    """Describe each log; one error line per damaged log (exit 1). A missing input, or one
    that is not a log, is a mistake (exit 2, nothing printed)."""
    from impactlab.cli.inputs import check_log_inputs
    from impactlab.errors import ImpactlabError
    from impactlab.logs.info import describe
    from impactlab.logs.inputs import find_logs
    from impactlab.text import terminal_text

    check_log_inputs(args.logs)
    failed = 0
    for i, path in enumerate(find_logs(args.logs)):
        try:
            text = describe(path)
        except ImpactlabError as exc:
            print(terminal_text(f"impactlab: error: {exc}"), file=sys.stderr)
            failed += 1
            continue
        print(terminal_text(("\n" if i else "") + text))
    return 1 if failed else 0
