"""Analyze: logs -> bounces, restitution, energy budgets, collisions, studies (docs/analysis.md)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from impactlab.packages import lazy_exports

if TYPE_CHECKING:
    from impactlab.analyze.job import run_analysis as run_analysis
    from impactlab.analyze.measure.analysis import RunAnalysis as RunAnalysis
    from impactlab.analyze.measure.analysis import analyze_run as analyze_run
    from impactlab.analyze.measure.analysis import analyze_runs as analyze_runs
    from impactlab.analyze.report.blocks import Block as Block
    from impactlab.analyze.report.blocks import Bullets as Bullets
    from impactlab.analyze.report.blocks import Column as Column
    from impactlab.analyze.report.blocks import Figure as Figure
    from impactlab.analyze.report.blocks import Heading as Heading
    from impactlab.analyze.report.blocks import Link as Link
    from impactlab.analyze.report.blocks import Paragraph as Paragraph
    from impactlab.analyze.report.blocks import Table as Table
    from impactlab.analyze.report.document import append_report_sections as append_report_sections
    from impactlab.analyze.tables.combine import AnalysisResult as AnalysisResult
    from impactlab.executors.base import Executor
    from impactlab.progress import Progress

if not TYPE_CHECKING:  # a type checker sees the imports above
    __getattr__ = lazy_exports(
        __name__,
        {
            "AnalysisResult": "impactlab.analyze.tables.combine",
            "RunAnalysis": "impactlab.analyze.measure.analysis",
            "analyze_run": "impactlab.analyze.measure.analysis",
            "analyze_runs": "impactlab.analyze.measure.analysis",
            "run_analysis": "impactlab.analyze.job",
            "append_report_sections": "impactlab.analyze.report.document",
            "Block": "impactlab.analyze.report.blocks",
            "Bullets": "impactlab.analyze.report.blocks",
            "Column": "impactlab.analyze.report.blocks",
            "Figure": "impactlab.analyze.report.blocks",
            "Heading": "impactlab.analyze.report.blocks",
            "Link": "impactlab.analyze.report.blocks",
            "Paragraph": "impactlab.analyze.report.blocks",
            "Table": "impactlab.analyze.report.blocks",
        },
    )


def analyze(
    logs: str | Path | Sequence[str | Path],
    *,
    out: str | Path | None = None,
    figures: bool = False,
    report: bool = False,
    executor: Executor | str | None = None,
    progress: Progress | None = None,
    verbose: bool = False,
) -> AnalysisResult:
    """Analyze logs and return the tables as polars frames.

    Args:
        logs: log files, folders (searched recursively for *.mcap) or glob patterns.
        out: a folder to write the tables (Parquet, summary.json) into; None writes nothing.
        figures: also draw the figures into `out`/figures (needs `out`).
        report: also write `out`/report.md (needs `out`).
        executor: "local" (default: in this process), "processes" (one worker process per
            CPU, from 8 logs; needs the `if __name__ == "__main__":` guard in a script),
            "ray", or an `impactlab.executors` executor.
        progress: called with each `impactlab.progress.ProgressEvent`; None: silent.
        verbose: report progress on the console (when `progress` is None).

    Returns:
        `AnalysisResult`: `runs`, `bounces`, `collisions`, `energy`, `phases`, `studies`,
        the inputs that `failed`, and the `files` written.

    Raises:
        LogError: no input names a log.
        OutputError: `out` cannot be written.
        ValueError: figures or report asked for without `out`.
        ExecutorError: executor="processes" reached again while a worker imports the script
            (no `if __name__ == "__main__":` guard); the message says so.
    """
    from impactlab.analyze.job import run_analysis
    from impactlab.executors.choose import executor_for
    from impactlab.progress import reporter

    if out is None and (figures or report):
        raise ValueError("figures and report are written into a folder: give out=...")
    inputs = [logs] if isinstance(logs, str | Path) else list(logs)
    with executor_for(executor) as chosen, reporter(progress, verbose) as shown:
        return run_analysis(
            inputs,
            None if out is None else Path(out),
            figures=figures,
            report=report,
            executor=chosen,
            progress=shown,
        )
