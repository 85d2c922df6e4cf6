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
from impactlab.executors.base import Executor, add_executor_options, make_executor

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
    p.add_argument(
        "--calibration",
        choices=("none", "quick", "medium", "full"),
        default="medium",
        help="restitution calibration grid for the report (medium: ~170 runs, ~40 s)",
    )
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
            calibration=args.calibration,
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
    calibration: str = "medium",
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
        from impactlab.executors.base import record_sweep

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
    if calibration != "none":
        from impactlab.calibrate.command import run_calibration

        echo(f"calibrating restitution ({calibration} grid) into {results_dir / 'calibration'}/")
        calibrated = run_calibration(results_dir / "calibration", grid=calibration, echo=echo)
        _append_calibration(report, calibrated)
    failed = bool(unstable or analysis.failed or (replay and len(replays) < len(logs)))
    return LabResult(report, logs, replays, 1 if failed else 0)


def _append_calibration(report: Path, result) -> None:
    """Append the calibration's summary and figures to the report."""
    lines = [
        "",
        "## Calibration: target against measured restitution",
        "",
        f"Contacts asking for `restitution = e`, recorded and measured by this analysis over "
        f"the {result.grid.name} grid ({result.points.height} runs); the bound is "
        "|e_measured - e_target| <= 0.005 for e = 0.2..0.99 at 1..10 m/s.",
        "",
        "| contact | runs | max abs error | mean abs error | max penetration / radius | worst |",
        "|---|---|---|---|---|---|",
    ]
    names = {"plane": "ball-plane, gravity", "ball": "ball-ball, zero gravity"}
    for kind, name in names.items():
        entry = result.summary.get(kind)
        if not entry:
            continue
        w = entry.get("worst") or {}
        worst = (
            f"e = {w['target']:g} at {w['speed_mps']:g} m/s: measured {w['e_measured']:.5f}"
            if w
            else "-"
        )
        lines.append(
            f"| {name} | {entry['runs']} | {entry['max_abs_error']:.5f} | "
            f"{entry['mean_abs_error']:.4f} | {entry['max_penetration_frac']:.4f} | {worst} |"
        )
    lines.append("")
    lines += [f"![calibration]({os.path.relpath(f, report.parent)})" for f in result.figures]
    details = result.out_dir / "calibration.md"
    lines += ["", f"Every point: [{details.name}]({os.path.relpath(details, report.parent)})."]
    with open(report, "a", encoding="utf-8") as stream:
        stream.write("\n".join(lines) + "\n")


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
