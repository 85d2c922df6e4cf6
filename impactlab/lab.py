"""The whole lab end to end: record every experiment, analyze, replay, calibrate, report.

The specs are those of `experiments` (by default `experiments/` in the working folder, or,
when that holds none, the handout's experiments shipped with impactlab). Logs go to
OUT/logs, tables, figures and the report (report.md, and report.html with the figures
embedded) to OUT/results, one Rerun recording per run to OUT/results/replays (linked from
the report). Complete logs from an earlier run of
the same specs are reused.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from impactlab.errors import SpecError
from impactlab.executors.base import Executor
from impactlab.files import write_text
from impactlab.progress import Progress, say
from impactlab.text import md_link, md_text

if TYPE_CHECKING:
    from impactlab.calibrate import CalibrationResult

DEFAULT_EXPERIMENTS = Path("experiments")


@dataclass(frozen=True)
class LabResult:
    """Where the lab put things and whether everything worked."""

    report: Path
    logs: list[Path]
    replays: list[Path]
    exit_code: int


def run_lab(
    out: Path,
    *,
    experiments: Path | None = None,
    overwrite: bool = False,
    replay: bool = True,
    calibration: str = "medium",
    executor: Executor | None = None,
    progress: Progress | None = None,
) -> LabResult:
    """Record, analyze and replay every experiment spec in `experiments`.

    Args:
        out: the output folder: logs/ and results/ (tables, figures, report, replays).
        experiments: the folder of experiment specs; None: `experiments/` here if it holds
            any, else the handout's experiments shipped with impactlab (said in one line).
        overwrite: record again runs whose complete log exists (else they are reused).
        replay: write one Rerun recording per run.
        calibration: the calibration grid for the report ("none" to skip it).
        executor: where recording and analysis tasks run (default: here); replays and the
            calibration run here.
        progress: receives every stage's progress and lines; None: silent.
    """
    from impactlab.analyze import analyze, write_report_html
    from impactlab.record import plan, record

    specs = _specs(experiments, progress)
    logs_dir, results_dir = out / "logs", out / "results"
    runs = plan(specs)
    say(
        progress,
        "lab",
        f"recording {len(runs)} run(s) of {len(specs)} experiment(s) into {logs_dir}/",
    )
    recorded = record(runs, out=logs_dir, executor=executor, overwrite=overwrite, progress=progress)
    logs = recorded.paths
    say(progress, "lab", f"analyzing {len(logs)} log(s) into {results_dir}/")
    analysis = analyze(
        logs, out=results_dir, figures=True, report=True, executor=executor, progress=progress
    )
    report = results_dir / "report.md"
    sections = [report.read_text(encoding="utf-8")]
    replays: list[Path] = []
    if replay:
        from impactlab.replay import replay as write_replays

        say(progress, "lab", f"writing {len(logs)} replay(s) into {results_dir / 'replays'}/")
        replays = write_replays(
            logs, out=results_dir / "replays", analysis=results_dir, progress=progress
        )
        sections.append(_replays_section(report, replays))
    if calibration != "none":
        from impactlab.calibrate import run_calibration

        where = results_dir / "calibration"
        say(progress, "lab", f"calibrating restitution ({calibration} grid) into {where}/")
        echo = (lambda line: say(progress, "calibrate", line)) if progress else (lambda _: None)
        calibrated = run_calibration(where, grid=calibration, echo=echo, progress=progress)
        sections.append(_calibration_section(report, calibrated))
    write_text(report, "".join(sections))
    write_report_html(report)
    failed = bool(recorded.exit_code or analysis.failed or (replay and len(replays) < len(logs)))
    return LabResult(report, logs, replays, 1 if failed else 0)


def _specs(experiments: Path | None, progress: Progress | None) -> list[Path]:
    """The spec files to run (see `run_lab`)."""
    from impactlab.examples import example_specs, packaged_experiments

    if experiments is None:
        specs = sorted(DEFAULT_EXPERIMENTS.glob("*.toml"))
        if specs:
            return specs
        say(
            progress,
            "lab",
            f"no {DEFAULT_EXPERIMENTS}/ specs here: running the handout's experiments shipped "
            f"with impactlab, {packaged_experiments()} (`impactlab examples` copies them to edit)",
        )
        return example_specs()
    specs = sorted(experiments.glob("*.toml"))
    if not specs:
        raise SpecError(
            str(experiments),
            "--experiments",
            "no experiment specs (*.toml) there (`impactlab examples DIR` copies the handout's "
            "into DIR; without --experiments the lab runs them)",
        )
    return specs


def _calibration_section(report: Path, result: CalibrationResult) -> str:
    """The report's section on the calibration: summary and figures."""
    lines = [
        "",
        "## Calibration: target against measured restitution",
        "",
        f"Contacts asking for `restitution = e`, recorded and measured by this analysis over "
        f"the {result.grid.name} grid ({result.grid.n_runs} runs); the bound is "
        "|e_measured - e_target| <= 0.005 at every impact speed in the contact's speed range "
        "(single impacts at 1..10 m/s, and every bounce of multi-bounce drops).",
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
    mb = result.summary.get("bounces")
    if mb and mb["in_range"]:
        w = mb["worst_in_range"]
        lines.append(
            f"| every bounce of {mb['runs']} drops, gravity | {mb['in_range']} bounces in range "
            f"| {mb['max_abs_error_in_range']:.5f} | | {mb['max_penetration_frac_in_range']:.4f} "
            f"| bounce {w['bounce']} at {w['v_in_mps']:.3g} m/s: measured {w['e_measured']:.5f}; "
            f"{mb['below_range']} below the range within "
            f"{mb['max_abs_diff_predicted_below'] or 0:.4f} of the prediction |"
        )
    lines.append("")
    lines += [f"![calibration]({os.path.relpath(f, report.parent)})" for f in result.figures]
    details = result.out_dir / "calibration.md"
    lines += ["", f"Every point: [{details.name}]({os.path.relpath(details, report.parent)})."]
    return "\n".join(lines) + "\n"


def _replays_section(report: Path, replays: list[Path]) -> str:
    """The report's section linking each run's Rerun recording."""
    lines = [
        "",
        "## Replays",
        "",
        "One Rerun recording per run (open with `rerun FILE.rrd`; see docs/replay.md):",
        "",
    ]
    lines += [
        f"- [{md_text(p.stem)}]({md_link(os.path.relpath(p, report.parent))})" for p in replays
    ]
    return "\n".join(lines) + "\n"
