"""The `impactlab` command line: record, info (and the later stages).

User mistakes (`ImpactlabError`) become one line on stderr and a non-zero exit code.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path

from impactlab import __version__
from impactlab.errors import ImpactlabError
from impactlab.executors.base import add_executor_options

EXPERIMENTS_DIR = Path("experiments")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand."""
    parser = argparse.ArgumentParser(
        prog="impactlab",
        description="Simulated impact experiments: record MuJoCo runs to MCAP logs, analyze "
        "them, replay them in Rerun, compare them. `impactlab lab` does it all.",
    )
    parser.add_argument("--version", action="version", version=f"impactlab {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    rec = sub.add_parser(
        "record",
        help="simulate experiment specs (.toml) or MJCF models (.xml), one MCAP log per run",
        description="Simulate each run of the given specs or MJCF models and write one MCAP "
        "log per run to the output folder.",
    )
    rec.add_argument("inputs", nargs="+", type=Path, metavar="SPEC_OR_MJCF")
    rec.add_argument("-o", "--out", type=Path, default=Path("logs"), help="output folder (logs/)")
    rec.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="PATH=VALUE",
        help="override a spec field, e.g. --set ball.mass=2 (repeatable; VALUE is TOML)",
    )
    rec.add_argument(
        "--duration", type=float, help="time limit in s for MJCF models (required for them)"
    )
    rec.add_argument(
        "--overwrite", action="store_true", help="re-run runs whose complete log already exists"
    )
    add_executor_options(rec)
    rec.set_defaults(func=_cmd_record)

    info = sub.add_parser("info", help="print what logs hold (run, outcome, channels)")
    info.add_argument("logs", nargs="+", type=Path, metavar="LOG")
    info.set_defaults(func=_cmd_info)
    for register in _stage_commands():
        register(sub)
    return parser


def _stage_commands():
    """The `register(sub)` functions of the other stages' commands, in help order."""
    from impactlab.analyze.command import register as analyze
    from impactlab.calibrate.command import register as calibrate
    from impactlab.diff_command import register as diff
    from impactlab.lab import register as lab
    from impactlab.replay.command import register as replay

    return [analyze, replay, diff, calibrate, lab]


def _cmd_record(args: argparse.Namespace) -> int:
    from impactlab.executors.base import check_executor
    from impactlab.record.job import plan, record

    check_executor(args.executor, args.address)
    runs = plan(args.inputs, overrides=args.overrides, duration=args.duration)
    if args.executor != "local":
        return _record_with_executor(runs, args)
    results = record(runs, args.out, overwrite=args.overwrite)
    unstable = [r for r in results if r.trajectory.verdict.outcome != "completed"]
    print(f"{len(results)} run(s) written to {args.out}/", end="")
    print(f", {len(unstable)} unstable" if unstable else "")
    return 1 if unstable else 0


def _record_with_executor(runs, args: argparse.Namespace) -> int:
    from impactlab.executors.base import make_executor, record_sweep

    executor = make_executor(args.executor, args.address)
    try:
        sweep = record_sweep(
            runs,
            args.out,
            executor,
            overwrite=args.overwrite,
            error=lambda line: print(line, file=sys.stderr),
        )
    finally:
        executor.close()
    written = len(sweep.recorded)
    print(f"{written} run(s) written to {args.out}/", end="")
    print(f", {len(sweep.unstable)} unstable" if sweep.unstable else "", end="")
    print(f", {len(sweep.failed)} failed" if sweep.failed else "")
    return sweep.exit_code


def _cmd_info(args: argparse.Namespace) -> int:
    from impactlab.logs.info import describe

    failed = 0
    for i, path in enumerate(args.logs):
        try:
            text = describe(path)
        except ImpactlabError as exc:
            print(f"impactlab: error: {exc}", file=sys.stderr)
            failed += 1
            continue
        print(("\n" if i else "") + text)
    return 1 if failed else 0


def _terminate(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # unwinds like Ctrl-C: partial files are removed on the way out


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    args = build_parser().parse_args(argv)
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _terminate)
    try:
        return int(args.func(args))
    except ImpactlabError as exc:
        print(f"impactlab: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("impactlab: interrupted", file=sys.stderr)
        return 130
