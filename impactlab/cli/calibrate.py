"""`impactlab calibrate [--grid quick|medium|full]`: target against measured restitution."""

from __future__ import annotations

import argparse
from pathlib import Path

from impactlab.cli.options import path

GRID_RUNS = {"quick": 43, "medium": 181, "full": 551}  # checked against the grids by a test


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the `calibrate` subcommand."""
    p = sub.add_parser(
        "calibrate",
        help="record a grid of calibrated impacts and compare target and measured restitution",
        description="Record ball-plane drops (gravity) and ball-ball collisions (zero gravity) "
        "over targets e, impact speeds and masses with calibrated contacts, and multi-bounce "
        "drops whose every bounce is checked (in the contact's speed range against the target, "
        "below it against the prediction); measure e with the analysis stage, and write "
        "tables, figures and calibration.md. Grids: "
        + ", ".join(f"{name} ({n} runs)" for name, n in GRID_RUNS.items())
        + "; quick is the default.",
    )
    p.add_argument(
        "-o", "--out", type=path, default=Path("calibration"), help="output folder (calibration/)"
    )
    p.add_argument("--quick", action="store_true", help=argparse.SUPPRESS)  # the default now
    p.add_argument(
        "--grid",
        choices=sorted(GRID_RUNS),
        default="quick",
        help="grid to run (default quick: 43 runs, about 20 s)",
    )
    p.add_argument("--targets", type=float, nargs="+", metavar="E", help="target e values")
    p.add_argument("--speeds", type=float, nargs="+", metavar="V", help="impact speeds in m/s")
    p.add_argument("--masses", type=float, nargs="+", metavar="M", help="masses in kg")
    p.add_argument(
        "--discard-logs", action="store_true", help="delete the MCAP logs after the analysis"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Calibrate; exit 0 when every point meets its bounds, else 1."""
    from impactlab.calibrate.job import run_calibration
    from impactlab.progress import console_progress

    progress = console_progress()
    try:
        result = run_calibration(
            args.out,
            grid=args.grid,
            targets=args.targets,
            speeds=args.speeds,
            masses=args.masses,
            keep_logs=not args.discard_logs,
            progress=progress,
        )
    finally:
        progress.close()
    return result.exit_code
