"""`impactlab analyze LOGS... -o results/`: tables, figures and report.md."""

from __future__ import annotations

import argparse
from pathlib import Path

from impactlab.cli.options import add_executor_options, path

ANALYSIS_TASKS = "impactlab.analyze.batch"  # the module of the analysis' executor tasks


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the `analyze` subcommand."""
    p = sub.add_parser(
        "analyze",
        help="analyze logs: energy, bounces, collisions, studies -> tables, figures, report",
        description="Analyze impactlab logs (files, folders or glob patterns, from any number "
        "of experiments and sweeps) and write Parquet tables, summary.json, PNG figures and "
        "report.md to the output folder.",
    )
    p.add_argument("logs", nargs="+", metavar="LOG", help="log files, folders or glob patterns")
    p.add_argument(
        "-o", "--out", type=path, default=Path("results"), help="output folder (results/)"
    )
    p.add_argument(
        "--no-figures",
        dest="figures",
        action="store_false",
        help="tables only: no figures, report.md without them (what batch jobs need; fastest)",
    )
    add_executor_options(p, default="processes")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Analyze into the output folder: tables, report and (unless --no-figures) figures,
    replacing its previous analysis as one set. Exit 2 and nothing written when no input
    names a readable log or the folder cannot be written; 1 when some inputs failed (one
    line each) and the others were analyzed."""
    from contextlib import closing

    from impactlab.executors.choose import make_executor
    from impactlab.executors.processes import ProcessExecutor
    from impactlab.logs.inputs import check_log_inputs, log_names
    from impactlab.progress import ConsoleProgress

    executor = make_executor(args.executor, args.address)  # a wrong option first (starts nothing)
    check_log_inputs(args.logs)
    with closing(executor), ConsoleProgress() as progress:
        # the workers import while this process does; a batch below min_items runs here
        if (
            isinstance(executor, ProcessExecutor)
            and len(log_names(args.logs)) >= executor.min_items
        ):
            executor.prestart([ANALYSIS_TASKS])
        from impactlab.analyze.job import run_analysis

        result = run_analysis(
            args.logs, args.out, figures=args.figures, executor=executor, progress=progress
        )
    return result.exit_code
