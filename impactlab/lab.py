"""The whole lab end to end: record every experiment, analyze, replay, report (and calibrate).

The specs are those of `experiments` (by default `experiments/` in the working folder, or,
when that holds none, the handout's experiments shipped with impactlab). Logs go to
OUT/logs, tables, figures and the report (report.md, and report.html with the figures
embedded; the details in report-appendix.md/.html) to OUT/results, one Rerun recording per
run to OUT/results/replays (linked from the appendix), and, when asked, the calibration
experiment to OUT/results/calibration (its table in the appendix). Complete logs from an
earlier run of the same specs are reused.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from impactlab.errors import SpecError
from impactlab.executors.base import Executor
from impactlab.files import full_disk_error
from impactlab.progress import Progress, say

if TYPE_CHECKING:
    from impactlab.analyze import Block

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
    calibration: bool = False,
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
        calibration: also record and analyze the calibration experiment
            (`impactlab.calibrate`), its table in the appendix.
        executor: where recording and analysis tasks run (default: here); replays and the
            calibration run here.
        progress: receives every stage's progress and lines; None: silent.
    """
    from impactlab.analyze import analyze, append_report_sections
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
    sections: list[Block] = []
    replays: list[Path] = []
    if replay:
        from impactlab.replay import replay as write_replays

        say(progress, "lab", f"writing {len(logs)} replay(s) into {results_dir / 'replays'}/")
        replays = write_replays(
            logs, out=results_dir / "replays", analysis=results_dir, progress=progress
        )
        sections += _replays_section(results_dir, replays)
    if calibration:
        from impactlab.calibrate import report_blocks, run_calibration

        where = results_dir / "calibration"
        say(progress, "lab", f"recording the calibration experiment into {where}/")
        echo = (lambda line: say(progress, "calibrate", line)) if progress else (lambda _: None)
        calibrated = run_calibration(where, echo=echo, progress=progress)
        sections += report_blocks(calibrated, results_dir)
    if sections:
        with full_disk_error(results_dir):
            append_report_sections(results_dir / "report-appendix.md", sections)
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


def _replays_section(results: Path, replays: list[Path]) -> list[Block]:
    """The appendix's section linking each run's Rerun recording."""
    from impactlab.analyze import Bullets, Heading, Link, Paragraph

    links = tuple((Link(p.stem, os.path.relpath(p, results)),) for p in replays)
    return [
        Heading("Replays"),
        Paragraph(("One Rerun recording per run (open with rerun FILE.rrd; see docs/replay.md):",)),
        Bullets(links),
    ]
