"""Record jobs: specs or MJCF files -> validated runs -> one MCAP log per run in an output folder.

Everything is validated before the first simulation, so a wrong input writes nothing.
"""

from __future__ import annotations

import hashlib
import re
import struct
import tempfile
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
from mcap.exceptions import McapError
from mcap.reader import make_reader
from tqdm import tqdm

from impactlab.errors import ImpactlabError, SpecError
from impactlab.logs import format as logformat
from impactlab.logs.writer import remove_stale_partials
from impactlab.record.contact_pairs import calibrated_pairs
from impactlab.record.log_rows import RunInfo, write_run_log
from impactlab.record.model import InstrumentedModel, model_from_mjcf, model_from_spec
from impactlab.record.simulate import RunRequest, Trajectory, simulate_batch
from impactlab.record.spec import RunSpec, spec_hash
from impactlab.record.sweep import load_runs

MJCF_SUFFIXES = (".xml", ".mjcf")
BATCH_RUNS = 4  # runs simulated side by side: enough for two threads, few runs in memory


@dataclass(frozen=True)
class PlannedRun:
    """A run ready to simulate: its file name, metadata and how to build and stop it."""

    info: RunInfo
    build: Callable[[], InstrumentedModel]
    spec: RunSpec | None
    max_time: float


@dataclass(frozen=True)
class RunResult:
    """What recording one run produced."""

    path: Path
    trajectory: Trajectory
    wall_s: float


def plan(inputs: Sequence[Path], *, overrides: Sequence[str] = (), duration: float | None = None):
    """Validate every input and return the runs to record, in order.

    Args:
        inputs: experiment specs (.toml) and/or MJCF models (.xml).
        overrides: `PATH=VALUE` settings for specs.
        duration: time limit in s for MJCF models (required for them).

    Raises:
        SpecError: any input, override or option is wrong.
    """
    runs: list[PlannedRun] = []
    for path in inputs:
        if path.suffix.lower() in MJCF_SUFFIXES:
            runs.append(_plan_mjcf(path, overrides=overrides, duration=duration))
        elif path.suffix.lower() == ".toml":
            if duration is not None:
                raise SpecError(
                    str(path),
                    "--duration",
                    "applies to MJCF models; for specs use --set stop.max_time=...",
                )
            runs += [_plan_spec(run) for run in load_runs(path, overrides)]
        else:
            raise SpecError(
                str(path), "", "expected an experiment spec (.toml) or an MJCF model (.xml)"
            )
    ids = [r.info.run_id for r in runs]
    dup = next((i for i in ids if ids.count(i) > 1), None)
    if dup is not None:
        raise SpecError(dup, "", "two inputs give the same run; remove one of them")
    return runs


def _plan_spec(run: RunSpec) -> PlannedRun:
    calibrated_pairs(run)  # contact targets fail now, before any run is simulated
    digest = run.spec_hash
    info = RunInfo(
        run_id=run_name(run.experiment, run.sweep_values, digest),
        experiment=run.experiment,
        description=run.description,
        source=run.source,
        spec=run.document,
        sweep=run.sweep_values,
        spec_hash=digest,
        log_every=run.log_every,
        sweep_index=run.sweep_index,
        sweep_size=run.sweep_size,
    )
    return PlannedRun(info, lambda: model_from_spec(run), run, run.stop.max_time)


def _plan_mjcf(path: Path, *, overrides: Sequence[str], duration: float | None) -> PlannedRun:
    if overrides:
        raise SpecError(str(path), "--set", "overrides apply to experiment specs, not MJCF models")
    if duration is None or not duration > 0:
        raise SpecError(str(path), "--duration", "an MJCF model needs --duration SECONDS > 0")
    inst = model_from_mjcf(path)  # validate now; rebuilt when run
    document = {"mjcf": str(path), "duration": duration, "xml_sha256": _sha256(inst.xml)}
    digest = spec_hash(document)
    info = RunInfo(
        run_id=run_name(path.stem, {}, digest),
        experiment=path.stem,
        description=f"user model {path.name}",
        source=str(path),
        spec=document,
        sweep={},
        spec_hash=digest,
        log_every=1,
    )
    return PlannedRun(info, lambda: inst, None, duration)


def _sha256(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def run_name(experiment: str, sweep_values: dict[str, Any] | Any, digest: str) -> str:
    """A readable, unique file stem: experiment, sweep values, first 8 hex of the spec hash."""
    parts = [experiment]
    for key, value in sweep_values.items():
        leaf = key.removeprefix("bodies.").removeprefix("contact.").removeprefix("options.")
        text = "_".join(f"{v:g}" for v in value) if isinstance(value, list) else str(value)
        parts.append(f"{leaf}={text}")
    stem = "-".join([*parts, digest[:8]])
    return re.sub(r"[^A-Za-z0-9._=+-]", "_", stem)


def check_writable(out_dir: Path) -> None:
    """Create the output folder and prove a file can be written there, before any simulation."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out_dir, prefix=".impactlab-write-test-"):
            pass
    except OSError as exc:
        raise SpecError(str(out_dir), "-o", f"cannot write there: {exc.strerror or exc}") from None


def batches(
    runs: Sequence[PlannedRun], size: int
) -> list[list[tuple[PlannedRun, InstrumentedModel]]]:
    """Consecutive runs that can share a rollout (same MuJoCo sizes and timestep), built."""
    out: list[list[tuple[PlannedRun, InstrumentedModel]]] = []
    key = None
    for run in runs:
        inst = run.build()
        m = inst.model
        this = (m.nq, m.nv, m.na, m.nu, m.nbody, m.ngeom, m.nsensordata, m.opt.timestep)
        if not out or this != key or len(out[-1]) >= size:
            out.append([])
            key = this
        out[-1].append((run, inst))
    return out


def is_complete(path: Path, spec_hash: str) -> bool:
    """Whether `path` is a finished log of this run (spec hash), by this MuJoCo and log format."""
    try:
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            if reader.get_summary() is None:
                return False
            meta = {m.name: m.metadata for m in reader.iter_metadata()}
    except (OSError, McapError, ValueError, EOFError, struct.error):
        return False
    run = meta.get(logformat.RUN_METADATA, {})
    same_tools = (run.get("mujoco_version"), run.get("log_format_version")) == (
        mujoco.__version__,
        logformat.LOG_FORMAT_VERSION,
    )
    return run.get("spec_hash") == spec_hash and same_tools and logformat.OUTCOME_METADATA in meta


def log_path(out_dir: Path, run: PlannedRun) -> Path:
    """Where a run's log goes: named by experiment, sweep point and spec hash."""
    return out_dir / f"{run.info.run_id}.mcap"


def record(
    runs: Sequence[PlannedRun],
    out_dir: Path,
    *,
    echo: Callable[[str], None] = print,
    batch_size: int = BATCH_RUNS,
    threads: int | None = None,
    overwrite: bool = False,
) -> list[RunResult]:
    """Record planned runs in batches of multi-threaded rollouts, one log per run.

    Each run's log is written as soon as its batch finishes; a progress bar shows when
    there are several runs. Runs whose complete log is already in `out_dir` are reused
    (not returned) unless `overwrite`; leftovers of interrupted runs are removed.
    """
    check_writable(out_dir)
    todo = [r for r in runs if overwrite or not is_complete(log_path(out_dir, r), r.info.spec_hash)]
    for run in todo:
        remove_stale_partials(log_path(out_dir, run))
    if len(todo) < len(runs):
        echo(f"reused {len(runs) - len(todo)} complete log(s) in {out_dir}/, running {len(todo)}")
    results = []
    bar = tqdm(total=len(todo), unit="run", disable=len(todo) < 2 or None, leave=False)
    groups = batches(todo, batch_size)

    def simulate(batch: list[tuple[PlannedRun, InstrumentedModel]]):
        start = time.perf_counter()
        requests = [
            RunRequest(inst, run.max_time, run.spec.stop if run.spec else None, run.info.log_every)
            for run, inst in batch
        ]
        return simulate_batch(requests, threads=threads), time.perf_counter() - start

    # the next batch simulates (MuJoCo releases the GIL) while this one's logs are written
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="impactlab-sim") as pool:
        pending = pool.submit(simulate, groups[0]) if groups else None
        for i, batch in enumerate(groups):
            trajectories, seconds = pending.result()
            if i + 1 < len(groups):
                pending = pool.submit(simulate, groups[i + 1])
            for (run, inst), traj in zip(batch, trajectories, strict=True):
                t0 = time.perf_counter()
                try:
                    path = write_run_log(log_path(out_dir, run), inst, run.info, traj)
                except OSError as exc:  # e.g. a full disk: the logs written so far are complete
                    raise ImpactlabError(
                        f"{log_path(out_dir, run)}: cannot write the log: {exc.strerror or exc} "
                        f"({len(results)} log(s) of this job written before it are complete)"
                    ) from None
                result = RunResult(path, traj, seconds / len(batch) + time.perf_counter() - t0)
                results.append(result)
                bar.update()
                for line in summary_lines(result):
                    bar.write(line) if not bar.disable else echo(line)
    bar.close()
    return results


def summary_lines(result: RunResult) -> list[str]:
    """One line per run, plus one per warning."""
    traj = result.trajectory
    v = traj.verdict
    t_end = traj.t_ns[-1] / 1e9 if traj.t_ns.size else 0.0
    line = (
        f"{result.path.name}: {v.outcome} ({v.reason}), t = {t_end:.4g} s, "
        f"{v.last_step + 1} steps, {traj.t_ns.size} logged, {result.wall_s:.2f} s"
    )
    return [line] + [f"warning: {result.path.stem}: {w}" for w in traj.warnings]
