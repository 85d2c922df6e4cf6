"""`impactlab calibrate`: the calibration experiment, every impact against its target e."""

from __future__ import annotations

import argparse
from pathlib import Path

from impactlab.cli.options import path


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the `calibrate` subcommand."""
    p = sub.add_parser(
        "calibrate",
        help="record the calibration experiment and check e against its target at every impact",
        description="Record the calibration experiment shipped with impactlab "
        "(experiments/calibration/: single impacts on the floor and head-on collisions at 1, 3 "
        "and 10 m/s over targets e and masses, and drops bouncing six times with every "
        "integrator), analyze it, and check every impact of a calibrated contact: in its speed "
        "range within 0.005 of the target, below it where the designer predicts. Writes the "
        "analysis with the table appended to its report; exit 0 when every impact meets its "
        "bound, 1 when one does not.",
    )
    p.add_argument(
        "-o", "--out", type=path, default=Path("calibration"), help="output folder (calibration/)"
    )
    p.add_argument(
        "--targets", type=float, nargs="+", metavar="E", help="the target e values to sweep"
    )
    p.add_argument(
        "--discard-logs", action="store_true", help="delete the MCAP logs after the analysis"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Calibrate; exit 0 when every impact meets its bound, else 1."""
    from impactlab.calibrate.job import run_calibration
    from impactlab.progress import ConsoleProgress

    with ConsoleProgress() as progress:
        result = run_calibration(
            args.out, targets=args.targets, keep_logs=not args.discard_logs, progress=progress
        )
    return result.exit_code
