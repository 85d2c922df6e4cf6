"""`impactlab calibrate`: record the calibration experiment, analyze it, check every impact."""

from __future__ import annotations

import math
import os
import shutil
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import polars as pl

from impactlab.analyze import (
    Block,
    Column,
    Heading,
    Link,
    Paragraph,
    Table,
    append_report_sections,
    run_analysis,
)
from impactlab.calibrate.table import BAND_MARGIN, calibration_table, summary
from impactlab.contact import RESTITUTION_FLOOR, RESTITUTION_TOLERANCE
from impactlab.errors import LogError, SpecError
from impactlab.examples import packaged_experiments
from impactlab.files import check_writable, full_disk_error, write_parquet
from impactlab.progress import Progress
from impactlab.record import plan, record_runs

TABLE = "calibration.parquet"


def calibration_specs() -> list[Path]:
    """The calibration experiment's specs: `experiments/calibration/*.toml`, shipped."""
    return sorted((packaged_experiments() / "calibration").glob("*.toml"))


@dataclass
class CalibrationResult:
    """What a calibration recorded, measured and wrote.

    Attributes:
        out_dir: the output folder: logs/ (unless discarded) and results/ (the analysis,
            its report with the calibration appended, `calibration.parquet`).
        table: every impact of a calibrated pair (`table.calibration_table`).
        runs: the runs recorded.
    """

    out_dir: Path
    table: pl.DataFrame
    runs: int

    @property
    def failures(self) -> pl.DataFrame:
        """The impacts that miss their bound (or pairs without an impact)."""
        return self.table.filter(~pl.col("ok"))

    @property
    def exit_code(self) -> int:
        """0 when every impact meets its bound, else 1."""
        return 1 if self.failures.height or self.table.is_empty() else 0


def run_calibration(
    out_dir: Path,
    *,
    specs: Sequence[Path | Mapping[str, Any]] | None = None,
    targets: Sequence[float] | None = None,
    keep_logs: bool = True,
    echo: Callable[[str], None] = print,
    progress: Progress | None = None,
) -> CalibrationResult:
    """Record the calibration specs, analyze the logs, check every impact against its target.

    Args:
        out_dir: the output folder (created); complete logs of an earlier run are reused.
        specs: spec files or documents with calibrated contacts (default: the shipped
            `calibration_specs`).
        targets: the target e values swept instead of the specs' (`contact.restitution`).
        keep_logs: keep the logs in out_dir/logs.
        echo: where the summary lines go.
        progress: receives the recording's and the analysis' progress; None: silent.

    Raises:
        SpecError: a target or spec is wrong (nothing written then).
        OutputError: the folder cannot be written (a full disk: nothing more is written).
        LogError: a log cannot be analyzed.
    """
    out_dir = Path(out_dir)
    overrides = [] if not targets else [f"contact.restitution={_checked(targets)}"]
    runs = plan(list(specs or calibration_specs()), overrides=overrides)
    created = not out_dir.exists()
    check_writable(out_dir)
    try:
        with full_disk_error(out_dir):
            return _calibrate(runs, out_dir, keep_logs=keep_logs, echo=echo, progress=progress)
    except BaseException:  # a folder this job created holds only its own partial work
        if created:
            shutil.rmtree(out_dir, ignore_errors=True)
        raise


def _checked(targets: Sequence[float]) -> list[float]:
    """The targets, each reachable and given once.

    Raises:
        SpecError: naming `--targets` and the value.
    """
    values = [float(e) for e in targets]
    for i, e in enumerate(values):
        if not (math.isfinite(e) and RESTITUTION_FLOOR <= e <= 1.0):
            rule = f"must be in [{RESTITUTION_FLOOR:.4f}, 1]"
            raise SpecError("--targets", "", f"{e!r} is out of range ({rule})")
        if e in values[:i]:
            raise SpecError("--targets", "", f"lists {e!r} twice: give each value once")
    return values


def _calibrate(
    runs: Sequence[Any],
    out_dir: Path,
    *,
    keep_logs: bool,
    echo: Callable[[str], None],
    progress: Progress | None,
) -> CalibrationResult:
    """`run_calibration` once the runs are planned and the folder checked."""
    echo(f"calibration: {len(runs)} runs into {out_dir}/")
    recorded = record_runs(runs, out_dir / "logs", progress=progress)
    results = out_dir / "results"
    analysis = run_analysis(recorded.paths, results, figures=False, progress=progress)
    if analysis.failed:
        raise LogError(*analysis.failed[0])
    table = calibration_table(runs, analysis.bounces, analysis.collisions)
    result = CalibrationResult(out_dir, table, len(runs))
    write_parquet(table, results / TABLE)
    append_report_sections(results / "report.md", report_blocks(result, results))
    for line in summary_lines(table):
        echo(line)
    if not keep_logs:
        shutil.rmtree(out_dir / "logs", ignore_errors=True)
    echo(f"calibration written to {results}/ (report.md)")
    return result


def summary_lines(table: pl.DataFrame) -> list[str]:
    """Per experiment and target: how close every impact came to its bound."""
    lines = [
        f"{'experiment':<24} {'target':>6} {'in range':>8} {'max|e-target|':>13} "
        f"{'outside':>7} {'max|e-predicted|':>16} {'failing':>7}"
    ]
    for r in summary(table).iter_rows(named=True):
        best = "-" if r["max_error"] is None else f"{r['max_error']:.4f}"
        off = "-" if r["max_off"] is None else f"{r['max_off']:.4f}"
        lines.append(
            f"{r['experiment']:<24} {r['target']:>6g} {r['in_range']:>8} {best:>13} "
            f"{r['outside']:>7} {off:>16} {r['failing']:>7}"
        )
    failing = table.filter(~pl.col("ok"))
    lines += [
        f"  not ok: {r['run_id']} {r['pair']}: {r['note']}" for r in failing.iter_rows(named=True)
    ]
    verdict = "every impact meets its bound" if failing.is_empty() else f"{failing.height} miss"
    lines.append(f"{table.height} impacts of calibrated pairs: {verdict}")
    return lines


COLUMNS = (
    Column("run_id", "Run id (log)"),
    Column("pair", "Pair"),
    Column("impact", "Impact"),
    Column("target", "Target e"),
    Column("speed_mps", "Impact speed", "m/s"),
    Column("in_range", "In the range"),
    Column("e", "e", digits=4),
    Column("error", "e - target", digits=2),
    Column("e_predicted", "Predicted e", digits=4),
    Column("penetration_m", "Penetration", "m"),
    Column("ok", "Within its bound"),
    Column("note", "Note"),
)


def report_blocks(result: CalibrationResult, folder: Path) -> list[Block]:
    """The report's section: the bound, the table of every impact (linked from `folder`)."""
    source = os.path.relpath(result.out_dir / "results" / TABLE, folder)
    failing = result.failures.height
    verdict = "every impact meets its bound" if not failing else f"{failing} impacts miss it"
    return [
        Heading("Calibration: e against its target at every impact"),
        Paragraph(
            (
                f"{result.runs} runs of contacts calibrated to a target e (the calibration "
                "experiment, experiments/calibration/), measured by this analysis: in the "
                f"contact's speed range e is within {RESTITUTION_TOLERANCE} of the target and "
                "the penetration within the designer's bound; outside it e lies where the "
                "designer's step emulation predicts, within the band over where in a step "
                f"the contact begins (± {BAND_MARGIN}). Here {verdict}. Every impact: ",
                Link(TABLE, source),
                ".",
            )
        ),
        Table(result.table, COLUMNS, source=source),
    ]
