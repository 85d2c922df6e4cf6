"""The analysis job: logs -> every run analyzed -> tables (and, when asked, files published as
one set: `publish`, docs/reliability.md)."""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from pathlib import Path

from impactlab.analyze.batch import AnalyzedLog, analyze_logs
from impactlab.analyze.publish import publish, staged
from impactlab.analyze.report.context import RunBrief, brief
from impactlab.analyze.tables.combine import AnalysisResult, TableReducer
from impactlab.analyze.write import write_all
from impactlab.executors.base import Executor
from impactlab.logs.inputs import require_log_names
from impactlab.progress import Progress, say


def run_analysis(
    inputs: Sequence[str | Path],
    out_dir: Path | None = None,
    *,
    figures: bool = True,
    report: bool = True,
    executor: Executor | None = None,
    progress: Progress | None = None,
) -> AnalysisResult:
    """Analyze logs; with `out_dir`, write the tables (and figures and report when asked).

    Args:
        inputs: log files, folders (searched recursively for *.mcap) or glob patterns.
        out_dir: the output folder (created; on a cluster, a path every machine sees);
            None: write nothing, return the tables.
        figures: draw the figures (each run's own and the summary ones) into out_dir/figures.
        report: write report.md (with the figures when they are drawn).
        executor: where the per-log analyses run (default: here, one after the other);
            the tables are reduced here either way, so the results are the same.
        progress: receives the job's progress and its lines; None: silent.

    Returns:
        The tables, the inputs that failed, and the files written.

    Raises:
        OutputError: the output folder cannot be written (exit code 2).
        NoLogs: no input names any log (exit code 2); an input among others that names none
            is reported as failed.
    """
    paths, empty = require_log_names(inputs, text=True)  # log names go into the tables
    out = None if out_dir is None else Path(out_dir)
    with contextlib.nullcontext(None) if out is None else staged(out) as stage:
        draw = stage is not None and figures
        fig_dir = stage / "figures" if draw and stage is not None else None
        # with a folder the tables are written as the batches finish (`TableReducer`): the
        # driver keeps each run's brief and figure paths only, never its frames or metadata
        reducer = TableReducer(folder=stage)
        briefs: list[RunBrief] = []
        run_figs: list[list[tuple[str, Path]]] = []
        failed: list[tuple[str, str]] = []
        partial: list[str] = []

        def take(d: AnalyzedLog) -> None:
            if d.error is not None:
                failed.append(d.error)
            if d.analysis is None:
                return
            a = reducer.take(d.analysis)
            if a.run.partial:
                problems = "; ".join(a.run.problems)
                partial.append(f"impactlab: warning: {a.run.path}: partial log ({problems})")
            briefs.append(brief(a))
            if d.figures:
                run_figs.append(d.figures)

        analyze_logs(paths, fig_dir=fig_dir, take=take, executor=executor, progress=progress)
        for where, why in empty:
            say(progress, "analyze", f"impactlab: error: {where}: {why}", "error")
        failed = [*empty, *failed]
        for line in partial:
            say(progress, "analyze", line, "warning")
        result = reducer.result(out, failed)
        if not briefs or out is None or stage is None:
            if stage is not None:  # nothing analyzed: nothing is published
                result.sources = {}
            return result
        written = write_all(
            result,
            briefs,
            run_figs,
            out=stage,
            figures=draw,
            report=report,
            executor=executor,
        )
        result.files = publish(stage, out, written)
        result.sources = {name: out / f"{name}.parquet" for name in result.sources}
        where = f"report: {out / 'report.md'}" if report else f"tables in {out}/"
        say(progress, "analyze", f"{len(briefs)} run(s) analyzed, {len(failed)} failed; {where}")
        return result
