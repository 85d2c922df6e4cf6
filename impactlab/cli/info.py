"""`impactlab info LOG...`: what logs hold."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the `info` subcommand."""
    info = sub.add_parser("info", help="print what logs hold (run, outcome, channels)")
    info.add_argument("logs", nargs="+", type=Path, metavar="LOG")
    info.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Describe each log; one error line per log that cannot be read (exit 1)."""
    from impactlab.errors import ImpactlabError
    from impactlab.logs.info import describe
    from impactlab.text import terminal_text

    failed = 0
    for i, path in enumerate(args.logs):
        try:
            text = describe(path)
        except ImpactlabError as exc:
            print(terminal_text(f"impactlab: error: {exc}"), file=sys.stderr)
            failed += 1
            continue
        print(terminal_text(("\n" if i else "") + text))
    return 1 if failed else 0
