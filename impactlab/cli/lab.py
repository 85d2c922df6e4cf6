"""`impactlab lab [-o lab-output]`: every experiment recorded, analyzed, replayed, reported."""

from __future__ import annotations

import argparse
from pathlib import Path

from impactlab.cli.options import add_executor_options, path
from impactlab.text import terminal_text


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the `lab` subcommand."""
    p = sub.add_parser(
        "lab",
        help="record every experiment, analyze the logs, write replays and the report",
        description="Run the whole lab: record each spec in the experiments folder, analyze "
        "all logs into tables, figures and a report, and write one Rerun replay per run. "
        "Without an experiments/ folder here, it runs the handout's experiments that ship "
        "with impactlab.",
    )
    p.add_argument("-o", "--out", type=path, default=Path("lab-output"), help="output folder")
    p.add_argument(
        "--experiments",
        type=path,
        help="folder of experiment specs (default: experiments/ if it holds any, else the "
        "handout's experiments shipped with impactlab; `impactlab examples` copies them)",
    )
    p.add_argument("--overwrite", action="store_true", help="re-record runs with complete logs")
    p.add_argument("--no-replay", action="store_true", help="skip writing Rerun recordings")
    p.add_argument(
        "--calibration",
        action="store_true",
        help="also record the calibration experiment (`impactlab calibrate`, about 30 s) and "
        "put its table in the appendix",
    )
    add_executor_options(p, default="processes")  # as analyze: workers for the analysis
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the lab; print where the report is."""
    from contextlib import closing

    from impactlab.executors.choose import make_executor
    from impactlab.lab import run_lab
    from impactlab.progress import ConsoleProgress

    with (
        closing(make_executor(args.executor, args.address)) as executor,
        ConsoleProgress() as progress,
    ):
        result = run_lab(
            args.out,
            experiments=args.experiments,
            overwrite=args.overwrite,
            replay=not args.no_replay,
            calibration=args.calibration,
            executor=executor,
            progress=progress,
        )
    print(terminal_text(f"report: {result.report}"))
    return result.exit_code
