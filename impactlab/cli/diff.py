"""`impactlab diff A.mcap B.mcap`: are two logs equal within tolerances? For people and CI.

Exit code 0 when equal within the tolerances, 1 when they differ, 2 on bad input (a file
that is missing or not an impactlab log: one line `impactlab: error: <path>: <problem>`, or a
wrong option). The report names both logs and, per difference, the channel, the field and the
time; `--json` prints the same as JSON on stdout.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from impactlab.text import one_line, terminal_text
from impactlab.tools import DEFAULT_ATOL, DEFAULT_IGNORED_META, DEFAULT_RTOL

EXIT_EQUAL, EXIT_DIFFERENT, EXIT_BAD_INPUT = 0, 1, 2


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the `diff` subcommand to the command line's subparsers."""
    p = sub.add_parser(
        "diff",
        help="compare two logs channel by channel and field by field (exit 1 when they differ)",
        description="Compare two impactlab logs: per channel, messages present in only one of "
        "them and, per field, the first time the values differ beyond the tolerance and the "
        "largest difference; metadata key by key; the attached model.xml. Numbers a and b are "
        "equal when |a - b| <= atol + rtol * max(|a|, |b|). Exit code 0: equal, 1: different, "
        "2: bad input.",
        epilog=f"Metadata keys ignored by default: {', '.join(DEFAULT_IGNORED_META)} "
        "(use --all-meta to compare them too). /tf and /scene are not compared: they are "
        "derived from the body states and the model.",
    )
    p.add_argument("a", type=Path, metavar="A.mcap", help="the reference log")
    p.add_argument("b", type=Path, metavar="B.mcap", help="the log to check")
    p.add_argument(
        "--atol",
        type=_tolerance,
        default=DEFAULT_ATOL,
        help=f"absolute tolerance, in each field's unit (default {DEFAULT_ATOL:g})",
    )
    p.add_argument(
        "--rtol",
        type=_tolerance,
        default=DEFAULT_RTOL,
        help=f"relative tolerance (default {DEFAULT_RTOL:g})",
    )
    p.add_argument(
        "--tol",
        dest="field_tols",
        type=_field_tolerance,
        action="append",
        default=[],
        metavar="FIELD=ATOL",
        help="absolute tolerance of one field, in every channel (normal_force=1e-6) or in one "
        "(/energy:total=1e-6); repeatable",
    )
    p.add_argument(
        "--ignore-meta",
        action="append",
        default=[],
        metavar="KEY",
        help="do not compare this metadata key (e.g. source, mujoco_version); repeatable",
    )
    p.add_argument(
        "--all-meta",
        action="store_true",
        help=f"also compare the keys ignored by default ({', '.join(DEFAULT_IGNORED_META)})",
    )
    p.add_argument("--json", action="store_true", help="print the comparison as JSON")
    p.set_defaults(func=run)


def _tolerance(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value >= 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text!r}")
    return value


def _field_tolerance(text: str) -> tuple[str, float]:
    name, sep, value = text.rpartition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(
            f"expected FIELD=ATOL or TOPIC:FIELD=ATOL (e.g. normal_force=1e-6), got {text!r}"
        )
    return name.strip(), _tolerance(value.strip())


def run(args: argparse.Namespace) -> int:
    """Compare; exit 0 equal, 1 different, 2 bad input."""
    from impactlab.errors import LogError
    from impactlab.logs.load import load_log
    from impactlab.tools.diff import Tolerance, diff_logs

    try:
        a, b = load_log(args.a), load_log(args.b)
    except LogError as exc:  # LogError's own exit code is 1, which here means "different"
        print(one_line(f"impactlab: error: {exc}"), file=sys.stderr)
        return EXIT_BAD_INPUT
    for log in (a, b):
        if log.partial:  # compared all the same: the differences show what is missing
            print(
                one_line(f"impactlab: warning: {log.path}: {'; '.join(log.problems)}"),
                file=sys.stderr,
            )
    ignored = [*([] if args.all_meta else DEFAULT_IGNORED_META), *args.ignore_meta]
    tolerance = Tolerance(atol=args.atol, rtol=args.rtol, fields=dict(args.field_tols))
    result = diff_logs(a, b, tolerance=tolerance, ignore_meta=ignored)
    if args.json:
        print(json.dumps(result.to_dict(), indent=2))
    else:
        print(terminal_text(result.report()))
    return EXIT_EQUAL if result.equal else EXIT_DIFFERENT
