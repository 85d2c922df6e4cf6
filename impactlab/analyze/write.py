"""Write an analysis: Parquet tables, summary.json, the summary figures and the report."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import polars as pl

from impactlab.analyze.report.context import Curve, RunBrief, Tables, labelled, repeated_runs
from impactlab.analyze.report.decimate_lines import LINE_BINS
from impactlab.analyze.report.document import answers, summary_answers, write_reports
from impactlab.analyze.report.figure_cache import FigureJob, draw_all, figure_job
from impactlab.analyze.report.standards import balls, drop_tests
from impactlab.analyze.tables.combine import TABLES, AnalysisResult
from impactlab.analyze.tables.decimate import ENERGY_ROWS_PER_RUN
from impactlab.analyze.tables.studies import study_parameters
from impactlab.executors.base import Executor
from impactlab.files import write_json, write_parquet
from impactlab.text import file_part

SUMMARY_SLICE = 1000
"""summary.json lists the runs from slices of this many rows of the runs table."""


def write_all(
    result: AnalysisResult,
    briefs: Sequence[RunBrief],
    run_figs: Sequence[list[tuple[str, Path]]],
    *,
    out: Path,
    figures: bool = True,
    report: bool = True,
    executor: Executor | None = None,
) -> list[Path]:
    """Write the tables, summary.json and (when asked) the summary figures and report.md.

    The bounces, collisions, energy and phases tables are in `out` already when the
    analysis streamed them there (`AnalysisResult.sources`); the others are written here.
    The report and summary read the small tables back once; the energy table is not read.

    Args:
        result: the tables.
        briefs: every run's `RunBrief` (for the summary figures; empty without figures).
        run_figs: each run's own figures, drawn already with its analysis.
        out: the output folder.
        figures: draw the summary figures (the runs' own are in `run_figs`).
        report: write report.md.
        executor: where the summary figures are drawn when its workers are up (default:
            here).

    Returns:
        Every file written: tables, figures, report.md, summary.json.
    """
    files = [write_parquet(result.runs, out / "runs.parquet")]
    for name in TABLES[1:]:
        source = result.sources.get(name)
        if isinstance(source, Path) and source.parent == out:
            files.append(source)
        else:
            files.append(write_parquet(result.table(name), out / f"{name}.parquet"))
    bounces, collisions, phases = (result.table(n) for n in ("bounces", "collisions", "phases"))
    params = {name: study_parameters(result.runs, name) for name in result.studies}
    figs: dict[str, list[Path]] = {}
    for made in run_figs:
        for kind, path in made:
            figs.setdefault(kind, []).append(path)
    same = repeated_runs(result.runs, params)  # each run drawn and reported once
    shown = [b for b in briefs if b.run_id not in same]
    jobs = []
    if figures:
        jobs = summary_figure_jobs(
            (bounces, collisions), result.studies, shown, params, out / "figures"
        )
        for kind, (path, _, _) in jobs:
            figs.setdefault(kind, []).append(path)
    files += [p for ps in figs.values() for p in ps]
    t = labelled(
        Tables(
            result.runs,
            bounces,
            collisions,
            phases,
            result.studies,
            params,
            {b.run_id: b for b in briefs},
            figs,
            list(result.failed),
            _stride_note(result),
            figures_asked=figures,
        )
    )
    replies = answers(t)
    summary = {  # the runs and studies listed slice by slice (`write_json`)
        "runs": _rows(result.runs),
        "failed": [{"path": p, "problem": why} for p, why in result.failed],
        "studies": {name: _rows(s) for name, s in result.studies.items()},
        "study_parameters": params,
        "answers": summary_answers(replies),
        "energy_table": t.energy_note,
    }
    # with workers, the summary figures are drawn by them (from a thread here) while
    # summary.json is written; without, here first. The report embeds them, so it waits
    todo = [job for _, job in jobs]
    workers = executor is not None and executor.name != "local"
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="impactlab-figures") as thread:
        drawing = thread.submit(draw_all, todo, executor) if todo and workers else None
        if drawing is None:
            draw_all(todo, executor)
        files.append(write_json(out / "summary.json", summary))
        if drawing is not None:
            drawing.result()
    if report:
        files += write_reports(t, out, replies)
    return files


def _rows(frame: pl.DataFrame) -> Iterator[dict[str, Any]]:
    """The frame's rows as dicts, SUMMARY_SLICE rows converted at a time."""
    for start in range(0, frame.height, SUMMARY_SLICE):
        yield from frame.slice(start, SUMMARY_SLICE).to_dicts()


def _stride_note(result: AnalysisResult) -> str:
    rows, n_max = result.energy_logged
    kept = result.scan("energy").select(pl.len()).collect().item()
    return (
        f"energy.parquet keeps every k-th logged step per run and body (k chosen so that at "
        f"most about {ENERGY_ROWS_PER_RUN} rows remain; here the longest run has {n_max} rows, "
        f"{kept} of {rows} rows kept); all quantities use every logged step, and the "
        f"figures' lines of more than {2 * LINE_BINS} points show the lowest and highest "
        f"point of each of {LINE_BINS} runs of steps."
    )


def summary_figure_jobs(
    tables: tuple[pl.DataFrame, pl.DataFrame],
    studies: dict[str, pl.DataFrame],
    briefs: Sequence[RunBrief],
    params: dict[str, list[str]],
    fig_dir: Path,
) -> list[tuple[str, FigureJob]]:
    """The figures over many runs to draw, nothing drawn yet: (kind, job) of each."""
    all_bounces, collisions = tables
    jobs: list[tuple[str, FigureJob]] = []
    fig_dir.mkdir(parents=True, exist_ok=True)
    by_exp: dict[str, list[RunBrief]] = {}
    for b in briefs:
        by_exp.setdefault(b.experiment, []).append(b)
    for exp, group in by_exp.items():
        grounded = [b for b in group if b.grounded]
        if grounded and _has_decay(all_bounces, [b.run_id for b in grounded]):
            labels = {b.run_id: b.label for b in grounded}
            path = fig_dir / f"bounce-decay-{file_part(exp)}.png"
            title = f"Bounce height decay: {exp}"
            job = figure_job(path, "bounce_decay_figure", all_bounces, labels, title=title)
            jobs.append(("decay", job))
    has_e = (all_bounces.height and all_bounces["e_velocity"].drop_nulls().len()) or (
        collisions.height and collisions["e_velocity"].drop_nulls().len()
    )
    if has_e:
        experiments = {b.run_id: b.experiment for b in briefs}
        path = fig_dir / "restitution-vs-speed.png"
        job = figure_job(
            path,
            "restitution_figure",
            all_bounces,
            collisions,
            experiments,
            targets=_targets(briefs),
            tests=[
                (r["test"], r["speed_mps"], r["lo"], r["hi"])
                for r in drop_tests(all_bounces, balls(briefs))
                .unique("test", keep="first", maintain_order=True)
                .iter_rows(named=True)
            ],
        )
        jobs.append(("restitution", job))
    for name, study in studies.items():
        param, group = params[name][0], by_exp.get(name, [])
        path, title = fig_dir / f"study-{file_part(name)}.png", f"Parameter study: {name}"
        if not group:
            continue
        if "e_collision" in study.columns and study["e_collision"].drop_nulls().len():
            m1, m2 = group[0].masses[:2]
            job = figure_job(
                path, "collision_study_figure", study, param, title=title, m1=m1, m2=m2
            )
            jobs.append(("study", job))
        elif "e_velocity_first" in study.columns:
            title += ": e of the first bounce"
            jobs.append(
                ("study", figure_job(path, "bounce_study_figure", study, param, title=title))
            )
    return jobs


def _has_decay(bounces: pl.DataFrame, run_ids: list[str]) -> bool:
    """Whether any of the runs has two complete bounces: a decay needs two heights."""
    if "complete" not in bounces.columns:
        return False
    done = bounces.filter(pl.col("complete") & pl.col("run_id").is_in(run_ids))
    return bool((done.group_by("run_id", "body").len()["len"] >= 2).any())


def _targets(briefs: Sequence[RunBrief]) -> dict[str, list[float | Curve]]:
    """experiment -> the restitution targets of its calibrated pairs, constants then e(v)
    curves (none: not calibrated)."""
    out: dict[str, list[float | Curve]] = {}
    for b in briefs:
        if b.targets or b.curves:
            out.setdefault(b.experiment, []).extend([*b.targets, *b.curves])
    return {
        name: sorted({t for t in ts if not isinstance(t, tuple)})
        + list(dict.fromkeys(t for t in ts if isinstance(t, tuple)))
        for name, ts in out.items()
    }
