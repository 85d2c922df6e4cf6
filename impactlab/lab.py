"""`impactlab lab`: the whole lab end to end: record every experiment, analyze, replay.

Logs go to OUT/logs, tables, figures and the report to OUT/results, one Rerun recording per
run to OUT/results/replays (linked from the report). Complete logs from an earlier run of
the same specs are reused.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from impactlab.errors import SpecError
from impactlab.executor import Executor, add_executor_options, make_executor

DEFAULT_EXPERIMENTS = Path("experiments")


@dataclass(frozen=True)
class LabResult:
    """Where the lab put things and whether everything worked."""

    report: Path
    logs: list[Path]
    replays: list[Path]
    exit_code: int


def register(sub: argparse._SubParsersAction) -> None:
    """Add the `lab` subcommand."""
    p = sub.add_parser(
        "lab",
        help="record every experiment, analyze the logs, write replays and the report",
        description="Run the whole lab: record each spec in the experiments folder, analyze "
        "all logs into tables, figures and a report, and write one Rerun replay per run.",
    )
    p.add_argument("-o", "--out", type=Path, default=Path("lab-output"), help="output folder")
    p.add_argument(
        "--experiments",
        type=Path,
        default=DEFAULT_EXPERIMENTS,
        help="folder of experiment specs (experiments/)",
    )
    p.add_argument("--overwrite", action="store_true", help="re-record runs with complete logs")
    p.add_argument("--no-replay", action="store_true", help="skip writing Rerun recordings")
    add_executor_options(p)
    p.set_defaults(func=_cmd_lab)


def _cmd_lab(args: argparse.Namespace) -> int:
    executor = make_executor(args.executor, args.address)
    try:
        result = run_lab(
            args.out,
            experiments=args.experiments,
            overwrite=args.overwrite,
            replay=not args.no_replay,
            executor=executor,
        )
    finally:
        executor.close()
    print(f"report: {result.report}")
    return result.exit_code


def run_lab(
    out: Path,
    *,
    experiments: Path = DEFAULT_EXPERIMENTS,
    overwrite: bool = False,
    replay: bool = True,
    echo: Callable[[str], None] = print,
    executor: Executor | None = None,
) -> LabResult:
    """Record, analyze and replay every experiment spec in `experiments`.

    `executor`: where recording and analysis tasks run (default: here); replays are
    written here.
    """
    from impactlab.analyze.command import run_analysis
    from impactlab.record.job import plan, record

    specs = sorted(experiments.glob("*.toml"))
    if not specs:
        raise SpecError(str(experiments), "--experiments", "no experiment specs (*.toml) there")
    logs_dir, results_dir = out / "logs", out / "results"
    runs = plan(specs)
    echo(f"recording {len(runs)} run(s) of {len(specs)} experiment(s) into {logs_dir}/")
    if executor is None or executor.name == "local":
        recorded = record(runs, logs_dir, overwrite=overwrite, echo=echo)
        unstable = [r for r in recorded if r.trajectory.verdict.outcome != "completed"]
    else:
        from impactlab.executor import record_sweep

        sweep = record_sweep(runs, logs_dir, executor, overwrite=overwrite, echo=echo)
        unstable = sweep.unstable + sweep.failed
    logs = [logs_dir / f"{r.info.run_id}.mcap" for r in runs]
    echo(f"analyzing {len(logs)} log(s) into {results_dir}/")
    analysis = run_analysis(logs, results_dir, echo=echo, executor=executor)
    replays: list[Path] = []
    report = results_dir / "report.md"
    if replay:
        from impactlab.replay.command import replay_logs

        echo(f"writing {len(logs)} replay(s) into {results_dir / 'replays'}/")
        replays = replay_logs(logs, out=results_dir / "replays", analysis_dir=results_dir)
        _link_replays(report, replays)
    failed = bool(unstable or analysis.failed or (replay and len(replays) < len(logs)))
    return LabResult(report, logs, replays, 1 if failed else 0)


def _link_replays(report: Path, replays: list[Path]) -> None:
    """Append a section linking each run's Rerun recording to the report."""
    lines = [
        "",
        "## Replays",
        "",
        "One Rerun recording per run (open with `rerun FILE.rrd`; see docs/replay.md):",
        "",
    ]
    lines += [f"- [{p.stem}]({os.path.relpath(p, report.parent)})" for p in replays]
    with open(report, "a", encoding="utf-8") as stream:
        stream.write("\n".join(lines) + "\n")
