"""Write an analysis: Parquet tables, summary.json, the summary figures and report.md."""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from pathlib import Path

import polars as pl

from impactlab.analyze.measure.analysis import RunAnalysis
from impactlab.analyze.report import answers
from impactlab.analyze.report.html import write_report_html
from impactlab.analyze.report.markdown import build_report
from impactlab.analyze.report.run_figures import run_label
from impactlab.analyze.tables.combine import AnalysisResult
from impactlab.analyze.tables.decimate import ENERGY_ROWS_PER_RUN
from impactlab.analyze.tables.studies import study_parameters
from impactlab.executors.base import Executor
from impactlab.files import write_json, write_parquet, write_text
from impactlab.text import file_part

TABLES = ("runs", "bounces", "collisions", "energy", "phases")


def write_all(
    result: AnalysisResult,
    analyses: Sequence[RunAnalysis],
    run_figs: Sequence[list[tuple[str, Path]]],
    *,
    out: Path,
    figures: bool = True,
    report: bool = True,
    previous: Path | None = None,
    executor: Executor | None = None,
) -> list[Path]:
    """Write the tables, summary.json and (when asked) the summary figures and report.md.

    Args:
        result: the tables.
        analyses: every run's analysis (its metadata and small tables).
        run_figs: each run's own figures, drawn already with its analysis.
        out: the output folder.
        figures: draw the summary figures (the runs' own are in `run_figs`).
        report: write report.md.
        previous: the figures of the last analysis into the same folder: those whose inputs
            did not change are copied from there, not drawn again (`figure_cache`).
        executor: where the summary figures are drawn when its workers are up (default:
            here).

    Returns:
        Every file written: tables, figures, report.md, summary.json.
    """
    # the energy table is decimated already (`outputs.with_decimated_energy`)
    files = [write_parquet(getattr(result, name), out / f"{name}.parquet") for name in TABLES]
    params = {name: study_parameters(result.runs, name) for name in result.studies}
    stride_note = _stride_note(result)
    figs: dict[str, list[Path]] = {}
    for made in run_figs:
        for kind, path in made:
            figs.setdefault(kind, []).append(path)
    if figures:
        for kind, paths in summary_figures(
            result, analyses, params, out / "figures", previous, executor
        ).items():
            figs.setdefault(kind, []).extend(paths)
    files += [p for ps in figs.values() for p in ps]
    if report:
        text = build_report(
            out_dir=out,
            runs=result.runs,
            bounces=result.bounces,
            collisions=result.collisions,
            phases=result.phases,
            studies=result.studies,
            params=params,
            figures=figs,
            failed=result.failed,
            energy_stride_note=stride_note,
        )
        files.append(write_text(out / "report.md", text))
        files.append(write_report_html(out / "report.md"))
    summary = {
        "runs": result.runs.to_dicts(),
        "failed": [{"path": p, "problem": why} for p, why in result.failed],
        "studies": {name: s.to_dicts() for name, s in result.studies.items()},
        "study_parameters": params,
        "answers": {
            "energy": answers.energy_answer(result.runs),
            "e_constant_across_bounces": answers.constancy_answer(result.runs, result.bounces),
            "e_against_drop_height": answers.height_answer(result.studies),
            "collision": answers.collision_answer(result.collisions, result.runs),
            "parameter_study": answers.study_answer(result.studies, params),
        },
        "energy_table": stride_note,
    }
    files.append(write_json(out / "summary.json", summary))
    return files


def _stride_note(result: AnalysisResult) -> str:
    rows, n_max = result.energy_logged
    return (
        f"`energy.parquet` keeps every k-th logged step per run and body (k chosen so that at "
        f"most about {ENERGY_ROWS_PER_RUN} rows remain; here the longest run has {n_max} rows, "
        f"{result.energy.height} of {rows} rows kept); figures and all quantities use every "
        "logged step."
    )


def summary_figures(
    result: AnalysisResult,
    analyses: Sequence[RunAnalysis],
    params: dict[str, list[str]],
    fig_dir: Path,
    previous: Path | None = None,
    executor: Executor | None = None,
) -> dict[str, list[Path]]:
    """Draw the figures over many runs (bounce decay, restitution, studies), by kind; those
    whose inputs did not change are copied from `previous`, the others drawn in the
    executor's workers when it has some (`figure_cache.draw_all`)."""
    from impactlab.analyze.report import figures
    from impactlab.analyze.report.figure_cache import draw_all, figure_key

    jobs: list[tuple[str, Path, str, Callable[[], Path]]] = []  # kind, path, key, draw

    fig_dir.mkdir(parents=True, exist_ok=True)
    by_exp: dict[str, list[RunAnalysis]] = {}
    for a in analyses:
        by_exp.setdefault(a.run.experiment, []).append(a)
    for exp, group in by_exp.items():
        grounded = [a for a in group if a.ground is not None and a.ground.surfaces]
        if grounded and _has_decay(result.bounces, [a.run.run_id for a in grounded]):
            labels = {a.run.run_id: run_label(a) for a in grounded}
            path = fig_dir / f"bounce-decay-{file_part(exp)}.png"
            title = f"Bounce height decay: {exp}"
            key = figure_key("decay", result.bounces, labels, title)
            draw = functools.partial(
                figures.bounce_decay_figure,
                result.bounces,
                labels,
                title=title,
                path=path.absolute(),
            )
            jobs.append(("decay", path, key, draw))
    has_e = (result.bounces.height and result.bounces["e_velocity"].drop_nulls().len()) or (
        result.collisions.height and result.collisions["e_measured"].drop_nulls().len()
    )
    if has_e:
        labels = {a.run.run_id: run_label(a) for a in analyses}
        bounces = (
            result.bounces
            if result.bounces.height
            else pl.DataFrame(schema={"complete": pl.Boolean})
        )
        experiments = {a.run.run_id: a.run.experiment for a in analyses}
        targets = _targets(analyses)
        path = fig_dir / "restitution-vs-speed.png"
        key = figure_key("restitution", bounces, result.collisions, labels, experiments, targets)
        draw = functools.partial(
            figures.restitution_figure,
            bounces,
            result.collisions,
            labels,
            path=path.absolute(),
            experiments=experiments,
            targets=targets,
        )
        jobs.append(("restitution", path, key, draw))
    for name, study in result.studies.items():
        param = params[name][0]
        group = by_exp[name]
        if "e_collision" in study.columns and study["e_collision"].drop_nulls().len():
            infos = list(group[0].run.body_info.values())
            path, title = fig_dir / f"study-{file_part(name)}.png", f"Parameter study: {name}"
            m1, m2 = infos[0].mass, infos[1].mass
            key = figure_key("collision-study", study, param, title, m1, m2)
            draw = functools.partial(
                figures.collision_study_figure,
                study,
                param,
                title=title,
                m1=m1,
                m2=m2,
                path=path.absolute(),
            )
            jobs.append(("study", path, key, draw))
        elif "e_velocity_first" in study.columns:
            path = fig_dir / f"study-{file_part(name)}.png"
            title = f"Parameter study: {name}: e of the first bounce"
            key = figure_key("bounce-study", study, param, title)
            draw = functools.partial(
                figures.bounce_study_figure, study, param, title=title, path=path.absolute()
            )
            jobs.append(("study", path, key, draw))
    paths = draw_all([job[1:] for job in jobs], previous, executor)
    figs: dict[str, list[Path]] = {}
    for (kind, *_), path in zip(jobs, paths, strict=True):
        figs.setdefault(kind, []).append(path)
    return figs


def _has_decay(bounces: pl.DataFrame, run_ids: list[str]) -> bool:
    """Whether any of the runs has two complete bounces: a decay needs two heights."""
    if bounces.is_empty() or "complete" not in bounces.columns:
        return False
    done = bounces.filter(pl.col("complete") & pl.col("run_id").is_in(run_ids))
    return bool(done.height) and int(done.group_by("run_id", "body").len()["len"].max()) >= 2


def _targets(analyses: Sequence[RunAnalysis]) -> dict[str, list[float]]:
    """experiment -> the restitution targets its specs asked for (none: not calibrated)."""
    out: dict[str, set[float]] = {}
    for a in analyses:
        contact = a.run.spec.get("contact") or {}
        asked = [contact.get("restitution")]
        asked += [p.get("restitution") for p in (contact.get("pairs") or {}).values()]
        for e in asked:
            if isinstance(e, int | float):
                out.setdefault(a.run.experiment, set()).add(float(e))
    return {name: sorted(es) for name, es in out.items()}
