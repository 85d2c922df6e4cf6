"""Executors: map a function over work items, here or on a cluster, and sweeps built on them.

An executor runs `fn(item)` for each item and yields one `TaskOutcome` per item as it
finishes: its value, or the reason it failed (one item failing never stops the others).
`LocalExecutor` runs the items one after the other in this process (the record-side
functions are multi-threaded themselves); `impactlab.executors.ray.RayExecutor` runs them as
Ray tasks on a cluster. `make_executor("local" | "ray", address)` picks one.

On top of that, two sweeps that work with any executor:

- `record_sweep`: groups the planned runs into tasks (`task_groups`); each task records
  its runs with batched rollouts and writes their logs straight to the output folder, named
  by the run's spec hash and written atomically, so a retried task overwrites its own
  partial output and never duplicates a run. A task returns only a `RunSummary` per run.
  Runs whose complete log already exists are reused (resume).
- `analyze_logs`: one task per log (`analyze_run(load_log(path))`, the run's figures drawn
  in the task), returning the run's small tables; the driver concatenates them.

The driver shows one progress bar for the sweep with finished / unstable / failed / reused
counts, and reports each failed run with its reason.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Generic, Protocol, TypeVar

from tqdm import tqdm

from impactlab.errors import ImpactlabError

T = TypeVar("T")
R = TypeVar("R")

EXECUTORS = ("local", "ray")
RAY_INSTALL_HINT = "pip install 'impactlab[ray]'"
MAX_TASK_RUNS = 16  # runs per task at most: a lost task costs little, results stream in
TASKS_PER_SLOT = 4  # tasks per worker slot at least (when there are enough runs): balance


class ExecutorError(ImpactlabError):
    """The executor cannot be used (Ray missing, cluster unreachable). Exit code 2."""

    exit_code = 2


@dataclass(frozen=True)
class TaskOutcome(Generic[R]):
    """What one item gave: its value, or `error` (the reason) when the task failed."""

    index: int
    value: R | None = None
    error: str | None = None
    wall_s: float = 0.0

    @property
    def ok(self) -> bool:
        return self.error is None


class Executor(Protocol):
    """Runs a function over work items; see the module docstring."""

    name: str

    @property
    def slots(self) -> int:
        """How many tasks run at the same time."""
        ...

    def map(self, fn: Callable[[Any], R], items: Sequence[Any]) -> Iterator[TaskOutcome[R]]:
        """Yield one outcome per item, in the order they finish."""
        ...

    def close(self) -> None:
        """Release what the executor started."""
        ...


def describe_error(exc: BaseException) -> str:
    """One line: the exception's type and message."""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


class LocalExecutor:
    """Items one after the other in this process (the functions use threads themselves)."""

    name = "local"
    slots = 1

    def map(self, fn: Callable[[Any], R], items: Sequence[Any]) -> Iterator[TaskOutcome[R]]:
        for i, item in enumerate(items):
            start = time.perf_counter()
            try:
                value = fn(item)
            except Exception as exc:  # one failed item never stops the others
                yield TaskOutcome(i, error=describe_error(exc), wall_s=time.perf_counter() - start)
            else:
                yield TaskOutcome(i, value=value, wall_s=time.perf_counter() - start)

    def close(self) -> None:
        pass

    def __enter__(self) -> LocalExecutor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def make_executor(name: str = "local", address: str | None = None) -> Executor:
    """The executor called `name` ("local" or "ray"; `address` is the Ray cluster's).

    Raises:
        ExecutorError: unknown name, an address for the local executor, or Ray is not
            installed (the message says how to install it).
    """
    check_executor(name, address)
    if name == "ray":
        from impactlab.executors.ray import RayExecutor

        return RayExecutor(address=address)
    return LocalExecutor()


def check_executor(name: str, address: str | None = None) -> None:
    """Raise `ExecutorError` now if `make_executor(name, address)` cannot work (starts nothing)."""
    if name not in EXECUTORS:
        raise ExecutorError(f"unknown executor {name!r}; choose one of {', '.join(EXECUTORS)}")
    if name == "local" and address:
        raise ExecutorError("--address applies to --executor ray")
    if name == "ray":
        require_ray()


def require_ray() -> None:
    """Raise `ExecutorError` with the install command when Ray cannot be imported."""
    try:
        import ray  # noqa: F401
    except ImportError:
        raise ExecutorError(
            f"--executor ray needs Ray, which is not installed: {RAY_INSTALL_HINT}"
        ) from None


def add_executor_options(parser) -> None:
    """Add `--executor` and `--address` to a subcommand's parser."""
    parser.add_argument(
        "--executor",
        choices=EXECUTORS,
        default="local",
        help="where tasks run: this machine (local, the default) or a Ray cluster (ray; "
        f"needs {RAY_INSTALL_HINT})",
    )
    parser.add_argument(
        "--address",
        metavar="ADDR",
        help="Ray cluster address HOST:PORT (default: start Ray on this machine); "
        "see docs/cluster.md",
    )


class SweepBar:
    """One progress bar for a sweep, with finished / unstable / failed / reused counts."""

    def __init__(self, total: int, *, reused: int = 0, unit: str = "run", echo=print) -> None:
        """`total`: items to do; `reused`: items found done before (counted, not in total)."""
        self.counts = {"finished": 0, "unstable": 0, "failed": 0, "reused": reused}
        self.echo = echo
        self.bar = tqdm(total=total, unit=unit, disable=total < 2 or None, leave=False)
        self._postfix()

    def _postfix(self) -> None:
        if not self.bar.disable:
            self.bar.set_postfix({k: v for k, v in self.counts.items() if v}, refresh=False)

    def add(self, key: str, n: int = 1) -> None:
        """Count `n` items done as `key` (a key of `counts`)."""
        self.counts[key] += n
        self.bar.update(n)
        self._postfix()

    def write(self, line: str) -> None:
        self.bar.write(line) if not self.bar.disable else self.echo(line)

    def close(self) -> None:
        self.bar.close()


# --- recording ---------------------------------------------------------------------------


@dataclass(frozen=True)
class RunSummary:
    """What the driver learns about one run (metadata-sized; the log stays on disk).

    Attributes:
        run_id, path: the run and its log.
        status: "recorded", "reused" (complete log found) or "failed" (no log).
        outcome, reason: the stop verdict ("completed", "unstable", ...) or, when the
            run failed, "" and why.
        warnings: the run's warnings.
        t_end_s, steps, logged: simulated time, steps and logged rows.
        wall_s: wall time spent on the run.
    """

    run_id: str
    path: Path
    status: str
    outcome: str = ""
    reason: str = ""
    warnings: tuple[str, ...] = ()
    t_end_s: float = 0.0
    steps: int = 0
    logged: int = 0
    wall_s: float = 0.0

    @property
    def failed(self) -> bool:
        return self.status == "failed"

    @property
    def unstable(self) -> bool:
        return self.status == "recorded" and self.outcome != "completed"

    def lines(self) -> list[str]:
        """The run's console lines, as `impactlab.record.job.summary_lines` words them."""
        if self.failed:
            return [f"{self.path.name}: failed: {self.reason}"]
        line = (
            f"{self.path.name}: {self.outcome} ({self.reason}), t = {self.t_end_s:.4g} s, "
            f"{self.steps} steps, {self.logged} logged, {self.wall_s:.2f} s"
        )
        return [line] + [f"warning: {self.path.stem}: {w}" for w in self.warnings]


def portable(run):
    """The planned run with a picklable `build` (rebuilt from the spec in the task).

    Spec runs rebuild their model from the `RunSpec`; MJCF runs carry their validated model
    (it pickles), so the workers need neither the MJCF file nor the spec file.
    """
    from impactlab.record.model import model_from_spec

    if run.spec is not None:
        build = functools.partial(model_from_spec, run.spec)
    else:
        build = functools.partial(_same, run.build())
    return dataclasses.replace(run, build=build)


def _same(value: T) -> T:
    return value


def task_groups(runs: Sequence[T], slots: int, *, max_runs: int = MAX_TASK_RUNS) -> list[list[T]]:
    """Consecutive runs cut into tasks: about TASKS_PER_SLOT tasks per slot, 1..max_runs runs.

    Consecutive runs are mostly points of one sweep, so a task's runs share a batched
    rollout; several tasks per slot keep every slot busy until the end, and a task stays
    small enough that a retry costs little and results stream to the driver.
    """
    if not runs:
        return []
    size = max(1, min(max_runs, math.ceil(len(runs) / (max(1, slots) * TASKS_PER_SLOT))))
    return [list(runs[i : i + size]) for i in range(0, len(runs), size)]


def record_group(
    runs: Sequence, out_dir: Path, *, threads: int | None = None, skip_complete: bool = True
) -> list[RunSummary]:
    """Record a group of planned runs in batched rollouts (the body of one record task).

    Each log is written atomically to `out_dir` under the run's spec-hash name; runs whose
    complete log is there already (a retried task) are not simulated again. A batch that
    fails, or a log that cannot be written, fails only its own runs.
    """
    from impactlab.record.job import BATCH_RUNS, batches, is_complete, log_path
    from impactlab.record.log_rows import write_run_log
    from impactlab.record.simulate import RunRequest, simulate_batch

    out: list[RunSummary] = []
    todo = []
    for run in runs:
        path = log_path(out_dir, run)
        if skip_complete and is_complete(path, run.info.spec_hash):
            out.append(RunSummary(run.info.run_id, path, "reused"))
        else:
            todo.append(run)
    try:
        groups = batches(todo, BATCH_RUNS)
    except Exception as exc:
        groups = []
        reason = describe_error(exc)
        out += [RunSummary(r.info.run_id, log_path(out_dir, r), "failed", "", reason) for r in todo]
    for batch in groups:
        start = time.perf_counter()
        requests = [
            RunRequest(inst, run.max_time, run.spec.stop if run.spec else None, run.info.log_every)
            for run, inst in batch
        ]
        try:
            trajectories = simulate_batch(requests, threads=threads)
        except Exception as exc:
            reason = describe_error(exc)
            out += [
                RunSummary(r.info.run_id, log_path(out_dir, r), "failed", "", reason)
                for r, _ in batch
            ]
            continue
        share = (time.perf_counter() - start) / len(batch)
        for (run, inst), traj in zip(batch, trajectories, strict=True):
            t0 = time.perf_counter()
            path = log_path(out_dir, run)
            try:
                write_run_log(path, inst, run.info, traj)
            except Exception as exc:
                reason = f"cannot write the log: {describe_error(exc)}"
                out.append(RunSummary(run.info.run_id, path, "failed", "", reason))
                continue
            v = traj.verdict
            out.append(
                RunSummary(
                    run.info.run_id,
                    path,
                    "recorded",
                    v.outcome,
                    v.reason,
                    tuple(traj.warnings),
                    traj.t_ns[-1] / 1e9 if traj.t_ns.size else 0.0,
                    v.last_step + 1,
                    int(traj.t_ns.size),
                    share + time.perf_counter() - t0,
                )
            )
    return out


@dataclass
class SweepResult:
    """Every run's summary, in plan order."""

    runs: list[RunSummary] = field(default_factory=list)

    def _with(self, test) -> list[RunSummary]:
        return [r for r in self.runs if test(r)]

    @property
    def recorded(self) -> list[RunSummary]:
        return self._with(lambda r: r.status == "recorded")

    @property
    def reused(self) -> list[RunSummary]:
        return self._with(lambda r: r.status == "reused")

    @property
    def failed(self) -> list[RunSummary]:
        return self._with(lambda r: r.failed)

    @property
    def unstable(self) -> list[RunSummary]:
        return self._with(lambda r: r.unstable)

    @property
    def exit_code(self) -> int:
        """0 when every run completed (or was reused), else 1."""
        return 1 if self.failed or self.unstable else 0


def record_sweep(
    runs: Sequence,
    out_dir: Path,
    executor: Executor,
    *,
    overwrite: bool = False,
    threads: int | None = None,
    echo: Callable[[str], None] = print,
    error: Callable[[str], None] | None = None,
) -> SweepResult:
    """Record planned runs with an executor; reuse complete logs unless `overwrite`.

    Args:
        runs: from `impactlab.record.job.plan`.
        out_dir: the output folder; on a cluster, a path every machine sees (shared).
        executor: where the tasks run.
        overwrite: re-record runs whose complete log exists.
        threads: rollout threads per task (default: one per task slot on a cluster, one
            per core locally).
        echo: where progress lines go; `error` gets one line per failed run (default echo).

    Returns:
        Every run's summary, in plan order.
    """
    from impactlab.logs.writer import remove_stale_partials
    from impactlab.record.job import check_writable, is_complete, log_path

    error = error or echo
    check_writable(out_dir)
    by_id: dict[str, RunSummary] = {}
    todo = []
    for run in runs:
        path = log_path(out_dir, run)
        if not overwrite and is_complete(path, run.info.spec_hash):
            by_id[run.info.run_id] = RunSummary(run.info.run_id, path, "reused")
        else:
            remove_stale_partials(path)
            todo.append(portable(run))
    if by_id:
        echo(f"reused {len(by_id)} complete log(s) in {out_dir}/, running {len(todo)}")
    groups = task_groups(todo, executor.slots) if todo else []
    if threads is None and executor.name != "local":
        threads = 1  # one rollout thread per task slot (a Ray task asks for one CPU)
    task = functools.partial(  # absolute: a worker's working folder is not the driver's
        record_group, out_dir=out_dir.absolute(), threads=threads, skip_complete=not overwrite
    )
    bar = SweepBar(len(todo), reused=len(by_id), echo=echo)
    try:
        for outcome in executor.map(task, groups) if groups else ():
            group = groups[outcome.index]
            if outcome.ok:
                summaries = [
                    dataclasses.replace(s, path=out_dir / s.path.name) for s in outcome.value or []
                ]
            else:
                summaries = [
                    RunSummary(r.info.run_id, log_path(out_dir, r), "failed", "", outcome.error)
                    for r in group
                ]
            for s in summaries:
                by_id[s.run_id] = s
                key = "failed" if s.failed else "unstable" if s.unstable else s.status
                bar.add("finished" if key == "recorded" else key)
                if s.failed:
                    error(f"impactlab: error: {s.run_id}: {s.reason}")
                elif s.status == "recorded":
                    for line in s.lines():
                        bar.write(line)
    finally:
        bar.close()
    return SweepResult([by_id[r.info.run_id] for r in runs if r.info.run_id in by_id])


# --- analysis ----------------------------------------------------------------------------


@dataclass(frozen=True)
class AnalyzedLog:
    """One log's analysis as a task returns it: the run's tables, its figures, or why not."""

    analysis: Any | None  # RunAnalysis without the bulky frames (see `slim`)
    figures: list[tuple[str, Path]]
    error: tuple[str, str] | None = None  # (path, problem) of an unreadable log


def analyze_one(item: tuple[Path, Path], fig_dir: Path) -> AnalyzedLog:
    """The body of one analysis task: analyze a log, draw its figures, return small tables.

    `item` is the log's absolute path (read here) and its path as the user gave it (what
    the tables and messages show, as in a local analysis).
    """
    from impactlab.analyze.analysis import analyze_run
    from impactlab.analyze.command import run_figures
    from impactlab.errors import LogError
    from impactlab.logs.load import load_log

    where, shown = item
    try:
        run = load_log(where)
        run.path = shown
        a = analyze_run(run)
    except LogError as exc:
        path = str(shown) if exc.path == str(where) else exc.path
        return AnalyzedLog(None, [], (path, exc.problem))
    fig_dir.mkdir(parents=True, exist_ok=True)
    return AnalyzedLog(slim(a), run_figures(a, fig_dir))


def slim(a):
    """The analysis without what only the run's own figures need (decoded channels, states).

    The tables (energy, phases, bounces, collisions, summary) and the run's metadata stay.
    """
    import polars as pl

    run = dataclasses.replace(
        a.run, bodies={}, contacts=pl.DataFrame(), energy=pl.DataFrame(), events=pl.DataFrame()
    )
    return dataclasses.replace(a, run=run, states=pl.DataFrame(), intervals=pl.DataFrame())


def analyze_logs(
    paths: Sequence[Path], fig_dir: Path, executor: Executor, *, echo: Callable[[str], None] = print
) -> list[AnalyzedLog]:
    """Analyze each log in a task; returns the results in the order of `paths`.

    A task that fails (not an unreadable log: that is an `AnalyzedLog.error`) gives an
    error entry with the task's reason.
    """
    out: list[AnalyzedLog | None] = [None] * len(paths)
    bar = SweepBar(len(paths), unit="log", echo=echo)
    # tasks get absolute paths (a worker's working folder is not the driver's); the
    # figures they return are named again under `fig_dir` as given
    task = functools.partial(analyze_one, fig_dir=fig_dir.absolute())
    items = [(Path(p).absolute(), Path(p)) for p in paths]
    try:
        for outcome in executor.map(task, items):
            if outcome.ok and outcome.value is not None:
                value = outcome.value
                figs = [(kind, fig_dir / path.name) for kind, path in value.figures]
                result = dataclasses.replace(value, figures=figs)
            else:
                result = AnalyzedLog(None, [], (str(paths[outcome.index]), outcome.error or ""))
            out[outcome.index] = result
            bar.add("failed" if result.error else "finished")
    finally:
        bar.close()
    return [r for r in out if r is not None]
