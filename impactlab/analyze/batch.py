"""Analyze many logs in batches (`analysis.analyze_runs`), here or one task per batch on an
executor: each log gives its `RunAnalysis`, slim, or why not; the results do not depend on where."""

from __future__ import annotations

import dataclasses
import functools
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import polars as pl

from impactlab.analyze.measure.analysis import RunAnalysis, analyze_runs
from impactlab.analyze.report.run_figures import run_figures
from impactlab.analyze.tables.decimate import with_decimated_energy
from impactlab.errors import LogError
from impactlab.executors.base import PROCESS_MIN_ITEMS, Executor
from impactlab.executors.processes import ProcessExecutor
from impactlab.files import FULL
from impactlab.logs.load import RunLog, load_log
from impactlab.progress import Progress, Tracker


@dataclass(frozen=True)
class AnalyzedLog:
    """One log's analysis: the run's tables and its own figures, or why not.

    Attributes:
        analysis: the run's analysis, without the bulky frames (`slim`).
        figures: (kind, path) of the run's own figures drawn with it.
        error: (path, problem) of an unreadable log.
    """

    analysis: RunAnalysis | None
    figures: list[tuple[str, Path]]
    error: tuple[str, str] | None = None


BATCH_LOGS = 64
"""At most this many logs are analyzed together (`analysis.analyze_runs`)."""
BATCH_BYTES = 32 << 20
"""...and at most this many bytes of log files (more only for one larger log)."""


def batches(items: Sequence[tuple[str | Path, str | Path]], parts: int = 1) -> list[list[int]]:
    """Consecutive groups of `items` (by index) to analyze together: `parts` groups of
    nearly equal size (fewer only when there are fewer logs), each cut further to at most
    BATCH_LOGS logs and BATCH_BYTES of files (more only for one larger log)."""
    n = len(items)
    k = min(max(parts, 1), n)
    out: list[list[int]] = []
    for g in range(k):
        size = 0
        first = len(out)
        for i in range(g * n // k, (g + 1) * n // k):
            try:
                nbytes = os.stat(items[i][0]).st_size
            except OSError:
                nbytes = 0
            if len(out) > first and len(out[-1]) < BATCH_LOGS and size + nbytes <= BATCH_BYTES:
                out[-1].append(i)
                size += nbytes
            else:
                out.append([i])
                size = nbytes
    return out


def analyze_some(
    items: Sequence[tuple[str | Path, str | Path]],
    fig_dir: Path | None,
) -> list[AnalyzedLog]:
    """Analyze some logs together and draw each run's own figures into `fig_dir` (None: no
    figures); one result per log, in order, its analysis `slim` (the body of a task).

    Each item is the log's path to read and its path as the user gave it (what the tables
    and messages show).
    """
    out: list[AnalyzedLog | None] = [None] * len(items)
    loaded: list[tuple[int, RunLog]] = []
    for i, (where_given, shown_given) in enumerate(items):
        where, shown = Path(where_given), Path(shown_given)
        try:
            run = load_log(where)
        except LogError as exc:
            path = str(shown) if exc.path == str(where) else exc.path
            out[i] = AnalyzedLog(None, [], (path, exc.problem))
            continue
        run.path = shown
        loaded.append((i, run))
    for group in distinct_batches(loaded):
        for (i, run), a in zip(group, analyze_runs([r for _, r in group]), strict=True):
            if isinstance(a, LogError):
                out[i] = AnalyzedLog(None, [], (str(run.path), a.problem))
                continue
            figures = []
            if fig_dir is not None:
                fig_dir.mkdir(parents=True, exist_ok=True)
                figures = run_figures(a, fig_dir)
            out[i] = AnalyzedLog(slim(a), figures)
    return [r for r in out if r is not None]


def distinct_batches(loaded: list[tuple[int, RunLog]]) -> list[list[tuple[int, RunLog]]]:
    """`loaded` in groups without a repeated run id (the same log given twice, re-runs of one
    spec in different folders), each in order; one group when the ids are distinct."""
    groups: list[list[tuple[int, RunLog]]] = []
    seen: list[set[str]] = []
    for entry in loaded:
        rid = entry[1].run_id
        k = next((k for k, ids in enumerate(seen) if rid not in ids), len(groups))
        if k == len(groups):
            groups.append([])
            seen.append(set())
        groups[k].append(entry)
        seen[k].add(rid)
    return groups


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


def analyze_logs(
    paths: Sequence[str | Path],
    *,
    fig_dir: Path | None,
    take: Callable[[AnalyzedLog], None],
    executor: Executor | None = None,
    progress: Progress | None = None,
) -> None:
    """Analyze each log (and draw its own figures when `fig_dir` is given): `take` receives
    each result in order of `paths` as soon as those before it are done, and none is kept,
    so memory holds the batches in flight, whatever the number of logs.

    A task that fails (not an unreadable log: that is an `AnalyzedLog.error`) gives an
    error entry with the task's reason.
    """
    tracker = Tracker("analyze", len(paths), progress)
    # one string per log, shared: a Path, which holds its parts too, is made per batch
    items = [(q, q) for q in map(str, paths)]
    out: list[AnalyzedLog | None] = [None] * len(paths)
    ready = 0  # out[:ready] has been taken

    def done(i: int, result: AnalyzedLog) -> None:
        nonlocal ready
        out[i] = result
        _count(tracker, result)
        while ready < len(out) and (r := out[ready]) is not None:
            take(r)
            out[ready] = None
            ready += 1

    if executor is None or executor.name == "local":
        for group in batches(items):
            for i, result in zip(
                group, analyze_some([items[i] for i in group], fig_dir), strict=True
            ):
                done(i, result)
        return
    # tasks get absolute paths (a worker's working folder is not the driver's); the
    # figures they return are named again under `fig_dir` as given
    task = functools.partial(analyze_some, fig_dir=None if fig_dir is None else fig_dir.absolute())
    parts = max(4 * executor.slots, PROCESS_MIN_ITEMS)
    if fig_dir is not None:  # a run's own figures cost more than its analysis: finer tasks
        parts = max(parts, 8 * executor.slots)
    groups = batches(items, parts=parts)
    absolute = [
        [(str(Path(items[i][0]).absolute()), items[i][1]) for i in group] for group in groups
    ]
    # worker processes, tables only: this process analyzes batches too, from the first while
    # the workers start (the analysis cannot bring it down: a log it cannot read is an error
    # entry). Not with figures: drawing here cost more than it gave (64-run sweep: 4.2 s ->
    # 4.7 s, and matplotlib in this process), tables only gained (2.0 s -> 1.65 s)
    outcomes = (
        executor.map(task, absolute, here=True)
        if isinstance(executor, ProcessExecutor) and fig_dir is None
        else executor.map(task, absolute)
    )
    for outcome in outcomes:
        group = groups[outcome.index]
        if outcome.ok and outcome.value is not None and len(outcome.value) == len(group):
            for i, value in zip(group, outcome.value, strict=True):
                figs = (
                    [(kind, fig_dir / path.name) for kind, path in value.figures]
                    if fig_dir is not None
                    else value.figures
                )
                done(i, dataclasses.replace(value, figures=figs))
        else:
            full = outcome.exception
            if isinstance(full, OSError) and full.errno in FULL:  # in a worker: the job's
                raise full
            for i in group:
                done(i, AnalyzedLog(None, [], (str(paths[i]), outcome.error or "")))


def _count(tracker: Tracker, result: AnalyzedLog | None) -> None:
    if result is not None and result.error is not None:
        tracker.add("failed")
        tracker.say(f"impactlab: error: {result.error[0]}: {result.error[1]}", "error")
    else:
        tracker.add("finished")
