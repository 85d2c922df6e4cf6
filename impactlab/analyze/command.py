"""`impactlab analyze LOGS... -o results/`: logs -> Parquet tables, summary.json, figures, report.

Each unreadable input gives one line on stderr (`impactlab: error: <path>: <problem>`) and the
others are still analyzed; the exit code is 1 when any input failed, 2 when the output folder
cannot be written.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from impactlab.analyze import answers, figures
from impactlab.analyze.analysis import RunAnalysis, analyze_run
from impactlab.analyze.outputs import (
    ENERGY_ROWS_PER_RUN,
    check_writable,
    decimate,
    write_parquet,
    write_summary,
)
from impactlab.analyze.report import build_report
from impactlab.analyze.studies import studies, study_parameters, with_parameters
from impactlab.errors import ImpactlabError, LogError
from impactlab.executors.base import Executor, add_executor_options, make_executor
from impactlab.logs.load import find_logs, load_log


@dataclass
class AnalysisResult:
    """What an analysis wrote and found.

    Attributes:
        out_dir: the output folder.
        runs: the runs table (one row per analyzed run, with sweep parameters and results).
        bounces, collisions, energy, phases: the other tables (energy decimated).
        studies: per swept experiment, its study table.
        failed: (path, problem) of each input that could not be analyzed.
        files: every file written.
    """

    out_dir: Path
    runs: pl.DataFrame
    bounces: pl.DataFrame
    collisions: pl.DataFrame
    energy: pl.DataFrame
    phases: pl.DataFrame
    studies: dict[str, pl.DataFrame]
    failed: list[tuple[str, str]] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        """0 when every input was analyzed, else 1."""
        return 1 if self.failed else 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add the `analyze` subcommand to the command line's subparsers."""
    p = sub.add_parser(
        "analyze",
        help="analyze logs: energy, bounces, collisions, studies -> tables, figures, report",
        description="Analyze impactlab logs (files, folders or glob patterns, from any number "
        "of experiments and sweeps) and write Parquet tables, summary.json, PNG figures and "
        "report.md to the output folder.",
    )
    p.add_argument("logs", nargs="+", metavar="LOG", help="log files, folders or glob patterns")
    p.add_argument(
        "-o", "--out", type=Path, default=Path("results"), help="output folder (results/)"
    )
    add_executor_options(p)
    p.set_defaults(func=_cmd_analyze)


def _cmd_analyze(args: argparse.Namespace) -> int:
    executor = make_executor(args.executor, args.address)
    try:
        return run_analysis(args.logs, args.out, executor=executor).exit_code
    finally:
        executor.close()


def _error(message: str) -> None:
    print(f"impactlab: error: {message}", file=sys.stderr)


def run_analysis(
    inputs: Sequence[str | Path],
    out_dir: Path,
    *,
    echo: Callable[[str], None] = print,
    executor: Executor | None = None,
) -> AnalysisResult:
    """Analyze logs and write the results.

    Args:
        inputs: log files, folders (searched recursively for *.mcap) or glob patterns.
        out_dir: the output folder (created; on a cluster, a path every machine sees).
        echo: where progress lines go.
        executor: where the per-log analyses run (default: here, one after the other);
            the tables are reduced here either way, so the results are the same.

    Returns:
        The tables and the list of inputs that failed (each also printed on stderr).

    Raises:
        OutputError: the output folder cannot be written (exit code 2).
        LogError: no input names any log.
    """
    out_dir = Path(out_dir)
    check_writable(out_dir)
    paths = find_logs(inputs)
    if not paths:
        raise LogError(" ".join(map(str, inputs)), "no logs found")
    analyses: list[RunAnalysis] = []
    failed: list[tuple[str, str]] = []
    run_figs: list[list[tuple[str, Path]]] | None = None
    if executor is None or executor.name == "local":
        for path in paths:
            try:
                analyses.append(analyze_run(load_log(path)))
            except LogError as exc:
                _error(str(exc))
                failed.append((exc.path, exc.problem))
    else:  # one task per log; the run's figures are drawn in its task
        from impactlab.executors.base import analyze_logs

        run_figs = []
        for item in analyze_logs(paths, out_dir / "figures", executor, echo=echo):
            if item.error is not None:
                _error(f"{item.error[0]}: {item.error[1]}")
                failed.append(item.error)
            else:
                analyses.append(item.analysis)
                run_figs.append(item.figures)
    for a in analyses:
        if a.run.partial:
            echo(f"warning: {a.run.path}: partial log ({'; '.join(a.run.problems)})")
    result = tables(analyses, out_dir, failed)
    if analyses:
        result.files = write_all(result, analyses, run_figs)
        echo(
            f"{len(analyses)} run(s) analyzed, {len(failed)} failed; "
            f"report: {out_dir / 'report.md'}"
        )
    return result


def tables(analyses: Sequence[RunAnalysis], out_dir: Path, failed) -> AnalysisResult:
    """Concatenate the per-run frames into the output tables."""

    def cat(frames: list[pl.DataFrame]) -> pl.DataFrame:
        frames = [f for f in frames if f.width]
        return pl.concat(frames, how="diagonal_relaxed") if frames else pl.DataFrame()

    runs = pl.DataFrame([a.summary for a in analyses], infer_schema_length=None)
    runs = with_parameters(runs) if runs.height else runs
    return AnalysisResult(
        out_dir=out_dir,
        runs=runs,
        bounces=cat([a.bounces for a in analyses]),
        collisions=cat([a.collisions for a in analyses]),
        energy=cat([a.energy for a in analyses]),
        phases=cat([a.phases for a in analyses]),
        studies=studies(runs) if runs.height else {},
        failed=list(failed),
    )


def run_title(a: RunAnalysis) -> str:
    """A figure title: experiment, sweep point, contact parameters and timestep."""
    sweep = ", ".join(f"{k.split('.')[-1]} = {v}" for k, v in a.run.sweep.items())
    contact = a.run.spec.get("contact", {})
    parts = [a.run.experiment + (f" ({sweep})" if sweep else "")]
    if contact:
        parts.append(f"solref {contact.get('solref')}, solimp {contact.get('solimp')}")
    parts.append(f"dt = {a.run.timestep_s:g} s")
    return "\n".join([parts[0], ", ".join(parts[1:])])


def _label(a: RunAnalysis) -> str:
    sweep = ", ".join(f"{k.split('.')[-1]} = {v}" for k, v in a.run.sweep.items())
    return sweep or a.run.run_id


FIGURE_RUNS_PER_SWEEP = 6  # per-run figures for at most this many points of a sweep


def draws_own_figures(sweep_index: int, sweep_size: int) -> bool:
    """Whether a sweep point gets its own figures: all of a small sweep, else evenly spread."""
    if sweep_size <= FIGURE_RUNS_PER_SWEEP:
        return True
    chosen = np.linspace(0, sweep_size - 1, FIGURE_RUNS_PER_SWEEP).round().astype(int)
    return sweep_index in set(chosen.tolist())


def run_figures(a: RunAnalysis, fig_dir: Path) -> list[tuple[str, Path]]:
    """Draw one run's own figures (energy, first collision); returns (kind, path) in order.

    In a sweep of many runs only `FIGURE_RUNS_PER_SWEEP` evenly spread points get them;
    the sweep's summary figures cover every run.
    """
    made: list[tuple[str, Path]] = []
    if not draws_own_figures(*a.run.sweep_point):
        return made
    contacts = a.phases.filter(pl.col("kind") == "contact")
    if a.run.plane_z is not None and a.energy.height:
        path = fig_dir / f"energy-{a.run.run_id}.png"
        made.append(
            ("energy", figures.energy_figure(a.energy, contacts, title=run_title(a), path=path))
        )
    for row in a.collisions.head(1).iter_rows(named=True):
        path = fig_dir / f"collision-{a.run.run_id}.png"
        made.append(
            (
                "collision",
                figures.collision_figure(a.states, row, contacts, title=run_title(a), path=path),
            )
        )
    return made


def write_all(
    result: AnalysisResult,
    analyses: Sequence[RunAnalysis],
    run_figs: Sequence[list[tuple[str, Path]]] | None = None,
) -> list[Path]:
    """Write tables, figures, summary.json and report.md; return the files written.

    `run_figs`: each run's own figures when they were drawn already (by its analysis task).
    """
    out = result.out_dir
    fig_dir = out / "figures"
    files: list[Path] = []
    energy_small = decimate(result.energy)
    for name, frame in (
        ("runs", result.runs),
        ("bounces", result.bounces),
        ("collisions", result.collisions),
        ("energy", energy_small),
        ("phases", result.phases),
    ):
        files.append(write_parquet(frame, out / f"{name}.parquet"))
    figs: dict[str, list[Path]] = {}
    for i, a in enumerate(analyses):
        made = run_figs[i] if run_figs is not None else run_figures(a, fig_dir)
        for kind, path in made:
            figs.setdefault(kind, []).append(path)
    by_exp: dict[str, list[RunAnalysis]] = {}
    for a in analyses:
        by_exp.setdefault(a.run.experiment, []).append(a)
    for exp, group in by_exp.items():
        if any(a.run.plane_z is not None for a in group) and result.bounces.height:
            labels = {a.run.run_id: _label(a) for a in group if a.run.plane_z is not None}
            figs.setdefault("decay", []).append(
                figures.bounce_decay_figure(
                    result.bounces,
                    labels,
                    title=f"Bounce height decay: {exp}",
                    path=fig_dir / f"bounce-decay-{exp}.png",
                )
            )
    has_e = (result.bounces.height and result.bounces["e_velocity"].drop_nulls().len()) or (
        result.collisions.height and result.collisions["e_measured"].drop_nulls().len()
    )
    if has_e:
        labels = {a.run.run_id: _label(a) for a in analyses}
        figs["restitution"] = [
            figures.restitution_figure(
                result.bounces
                if result.bounces.height
                else pl.DataFrame(schema={"complete": pl.Boolean}),
                result.collisions,
                labels,
                path=fig_dir / "restitution-vs-speed.png",
            )
        ]
    params = {name: study_parameters(result.runs, name) for name in result.studies}
    for name, study in result.studies.items():
        param = params[name][0]
        group = by_exp[name]
        if "e_collision" in study.columns and study["e_collision"].drop_nulls().len():
            infos = list(group[0].run.body_info.values())
            figs.setdefault("study", []).append(
                figures.collision_study_figure(
                    study,
                    param,
                    title=f"Parameter study: {name}",
                    m1=infos[0].mass,
                    m2=infos[1].mass,
                    path=fig_dir / f"study-{name}.png",
                )
            )
        elif "e_velocity_first" in study.columns:
            figs.setdefault("study", []).append(
                figures.bounce_study_figure(
                    study,
                    param,
                    title=f"Parameter study: {name}: e of the first bounce",
                    path=fig_dir / f"study-{name}.png",
                )
            )
    files += [p for ps in figs.values() for p in ps]
    n_max = (
        result.energy.group_by("run_id", "body").len()["len"].max() if result.energy.height else 0
    )
    stride_note = (
        f"`energy.parquet` keeps every k-th logged step per run and body (k chosen so that at "
        f"most about {ENERGY_ROWS_PER_RUN} rows remain; here the longest run has {n_max} rows, "
        f"{energy_small.height} of {result.energy.height} rows kept); figures and all "
        "quantities use every logged step."
    )
    failed = result.failed
    report = build_report(
        out_dir=out,
        runs=result.runs,
        bounces=result.bounces,
        collisions=result.collisions,
        phases=result.phases,
        studies=result.studies,
        params=params,
        figures=figs,
        failed=failed,
        energy_stride_note=stride_note,
    )
    (out / "report.md").write_text(report)
    files.append(out / "report.md")
    summary = {
        "runs": result.runs.to_dicts(),
        "failed": [{"path": p, "problem": why} for p, why in failed],
        "studies": {name: s.to_dicts() for name, s in result.studies.items()},
        "study_parameters": params,
        "answers": {
            "energy": answers.energy_answer(result.runs),
            "e_constant_across_bounces": answers.constancy_answer(result.runs, result.bounces),
            "e_against_drop_height": answers.height_answer(result.studies),
            "collision": answers.collision_answer(result.collisions),
            "parameter_study": answers.study_answer(result.studies, params),
        },
        "energy_table": stride_note,
    }
    files.append(write_summary(json.loads(json.dumps(summary, default=str)), out / "summary.json"))
    return files


__all__ = ["AnalysisResult", "ImpactlabError", "register", "run_analysis"]
