"""`impactlab record SPEC_OR_MJCF... -o logs/`."""

from __future__ import annotations

import argparse
from pathlib import Path

from impactlab.cli.options import add_executor_options, path, seconds, started
from impactlab.text import terminal_text


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the `record` subcommand."""
    rec = sub.add_parser(
        "record",
        help="simulate experiment specs (.toml) or MJCF models (.xml), one MCAP log per run",
        description="Simulate each run of the given specs or MJCF models and write one MCAP "
        "log per run to the output folder.",
    )
    rec.add_argument("inputs", nargs="+", type=path, metavar="SPEC_OR_MJCF")
    rec.add_argument("-o", "--out", type=path, default=Path("logs"), help="output folder (logs/)")
    rec.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="PATH=VALUE",
        help="override a spec field, e.g. --set ball.mass=2, or an MJCF model's run options "
        "(stop.*, logging.*, keyframe), e.g. --set logging.every=10 or --set keyframe=home "
        "(the model's keyframe the run starts from) (repeatable; VALUE is TOML)",
    )
    rec.add_argument(
        "--duration",
        type=seconds,
        help="time limit in s for MJCF models (or --set stop.max_time=...; one is required)",
    )
    rec.add_argument(
        "--overwrite", action="store_true", help="re-run runs whose complete log already exists"
    )
    rec.add_argument(
        "--allow-large",
        action="store_true",
        help="record even a job beyond the work limits (more than 100,000 runs, a run of "
        "more than 1e8 steps, 1e9 steps in all, 20 GB of logs or more than the free space; "
        "see docs/reliability.md)",
    )
    add_executor_options(rec)
    rec.set_defaults(func=run, gc_started_by_command=True)


def run(args: argparse.Namespace) -> int:
    """Plan (everything validated first), record, print one line per run and a summary."""
    from contextlib import closing

    from impactlab.executors.choose import make_executor
    from impactlab.progress import ConsoleProgress
    from impactlab.record.recorder import record_runs

    executor = make_executor(args.executor, args.address)
    from impactlab.record.planner import plan

    runs = plan(
        args.inputs,
        overrides=args.overrides,
        duration=args.duration,
        allow_large=args.allow_large,
    )
    started()
    with closing(executor), ConsoleProgress() as progress:
        result = record_runs(
            runs,
            args.out,
            executor=executor,
            overwrite=args.overwrite,
            allow_large=args.allow_large,
            progress=progress,
        )
    print(terminal_text(result.summary(args.out)))
    return result.exit_code
