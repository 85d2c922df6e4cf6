"""Analyze many logs: one after the other here, or one task per log on an executor.

Each log gives its `RunAnalysis` (tables and metadata; on an executor without the bulky
frames, see `slim`) or the reason it could not be read. The driver reduces the results
into the output tables either way, so the results do not depend on where the logs were
analyzed.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import polars as pl

from impactlab.analyze.analysis import RunAnalysis, analyze_run
from impactlab.analyze.outputs import with_decimated_energy
from impactlab.analyze.run_figures import run_figures
from impactlab.analyze.tables import TableReducer
from impactlab.errors import LogError
from impactlab.executors.base import Executor
from impactlab.logs.load import load_log
from impactlab.progress import Progress, Tracker


@dataclass(frozen=True)
class AnalyzedLog:
    """One log's analysis: the run's tables and its own figures, or why not.

    Attributes:
        analysis: the run's analysis (without the bulky frames when it came from a task).
        figures: (kind, path) of the run's own figures drawn with it.
        error: (path, problem) of an unreadable log.
    """

    analysis: RunAnalysis | None
    figures: list[tuple[str, Path]]
    error: tuple[str, str] | None = None


def analyze_one(
    item: tuple[Path, Path], fig_dir: Path | None, previous: Path | None = None
) -> AnalyzedLog:
    """Analyze one log and draw its own figures into `fig_dir` (None: no figures).

    `item` is the log's path to read and its path as the user gave it (what the tables
    and messages show); `previous` holds the figures of the last analysis into the same
    folder (unchanged ones are copied from there, not drawn again).
    """
    where, shown = item
    try:
        run = load_log(where)
        run.path = shown
        a = analyze_run(run)
    except LogError as exc:
        path = str(shown) if exc.path == str(where) else exc.path
        return AnalyzedLog(None, [], (path, exc.problem))
    figures = []
    if fig_dir is not None:
        fig_dir.mkdir(parents=True, exist_ok=True)
        figures = run_figures(a, fig_dir, previous)
    return AnalyzedLog(a, figures)


def slim(a: RunAnalysis) -> RunAnalysis:
    """The analysis without what only the run's own figures need (decoded channels, states).

    The tables (phases, bounces, collisions, summary; energy decimated as it is written,
    `outputs.decimate`) and the run's metadata stay.
    """
    a = with_decimated_energy(a)
    run = dataclasses.replace(
        a.run,
        bodies={},
        contacts=pl.DataFrame(),
        energy=pl.DataFrame(),
        events=pl.DataFrame(),
        clearance=pl.DataFrame(),
    )
    ground = None if a.ground is None else dataclasses.replace(a.ground, clearance=pl.DataFrame())
    return dataclasses.replace(
        a, run=run, states=pl.DataFrame(), intervals=pl.DataFrame(), ground=ground
    )


def _task(
    item: tuple[Path, Path], fig_dir: Path | None, previous: Path | None = None
) -> AnalyzedLog:
    """The body of one executor task: as `analyze_one`, returning small tables only."""
    result = analyze_one(item, fig_dir, previous)
    if result.analysis is None:
        return result
    return dataclasses.replace(result, analysis=slim(result.analysis))


def analyze_logs(
    paths: Sequence[Path],
    *,
    fig_dir: Path | None,
    previous: Path | None = None,
    executor: Executor | None = None,
    progress: Progress | None = None,
    reducer: TableReducer | None = None,
) -> list[AnalyzedLog]:
    """Analyze each log (and draw its own figures when `fig_dir` is given), in order of `paths`.

    `previous`: the figures of the last analysis into the same folder (see `analyze_one`).
    `reducer`: takes each run's tables, in order of `paths`, as soon as it can (the
    analyses returned then keep only the run's metadata): memory flat in the number of logs.

    A task that fails (not an unreadable log: that is an `AnalyzedLog.error`) gives an
    error entry with the task's reason.
    """
    tracker = Tracker("analyze", len(paths), progress)
    items = [(Path(p), Path(p)) for p in paths]
    out: list[AnalyzedLog | None] = [None] * len(paths)
    ready = 0  # out[:ready] has gone through the reducer

    def done(i: int, result: AnalyzedLog) -> None:
        nonlocal ready
        out[i] = result
        _count(tracker, result)
        while ready < len(out) and (r := out[ready]) is not None:
            if reducer is not None and r.analysis is not None:
                out[ready] = dataclasses.replace(r, analysis=reducer.take(r.analysis))
            ready += 1

    if executor is None or executor.name == "local":
        for i, item in enumerate(items):
            done(i, _task(item, fig_dir, previous))  # slim at once
        return [r for r in out if r is not None]
    # tasks get absolute paths (a worker's working folder is not the driver's); the
    # figures they return are named again under `fig_dir` as given
    task = functools.partial(
        _task,
        fig_dir=None if fig_dir is None else fig_dir.absolute(),
        previous=None if previous is None else previous.absolute(),
    )
    absolute = [(p.absolute(), shown) for p, shown in items]
    for outcome in executor.map(task, absolute):
        if outcome.ok and outcome.value is not None:
            value = outcome.value
            figs = [(kind, Path(fig_dir) / path.name) for kind, path in value.figures]
            result = dataclasses.replace(value, figures=figs)
        else:
            result = AnalyzedLog(None, [], (str(paths[outcome.index]), outcome.error or ""))
        done(outcome.index, result)
    return [r for r in out if r is not None]


def _count(tracker: Tracker, result: AnalyzedLog | None) -> None:
    if result is not None and result.error is not None:
        tracker.add("failed")
        tracker.say(f"impactlab: error: {result.error[0]}: {result.error[1]}", "error")
    else:
        tracker.add("finished")
