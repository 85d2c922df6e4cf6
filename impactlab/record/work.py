"""The work a record job asks for, estimated before anything is simulated; absurd jobs refused."""

from __future__ import annotations

import math
import shutil
from dataclasses import dataclass
from pathlib import Path

from impactlab.errors import ImpactlabError

MAX_RUNS = 100_000  # runs in one job
MAX_RUN_STEPS = 100_000_000  # steps of one run (about 10 minutes of simulation)
MAX_JOB_STEPS = 1_000_000_000  # steps of the whole job (about 2 hours on two cores)
MAX_LOG_BYTES = 20 * 10**9  # logs written by the job
US_PER_STEP = 7.0  # wall time per step simulated and logged on two cores (docs/performance.md)
LOG_BYTES_PER_LOG = 40_000  # whatever its length: schemas, metadata, the model, the index
LOG_BYTES_PER_BODY = 2_000  # whatever its length, per body: its channels and metadata
# (measured: a log of 3 rows takes 38,139 bytes with one body, 39,378 with two: `impactlab
# record` of a spec with max_time = 2 timesteps, log format 3, MuJoCo 4.0.0)
LOG_BYTES_PER_ROW = 80  # per logged row: energy, work and the row's share of the chunk overhead
LOG_BYTES_PER_BODY_ROW = 130  # per logged row and body: its state, transform, clearance (zstd)
ALLOW_FLAG = "--allow-large"


def run_steps(max_time_s: float, timestep_s: float) -> int:
    """Rows of a run that reaches its time limit: steps 0 .. ceil(max_time / timestep)."""
    return max(1, math.ceil(max_time_s / timestep_s - 1e-9)) + 1


@dataclass(frozen=True)
class Work:
    """What a job (or part of it) asks for, at most (runs may stop early on events)."""

    runs: int = 0
    steps: int = 0
    longest_run_steps: int = 0
    log_bytes: int = 0

    def __add__(self, other: Work) -> Work:
        return Work(
            self.runs + other.runs,
            self.steps + other.steps,
            max(self.longest_run_steps, other.longest_run_steps),
            self.log_bytes + other.log_bytes,
        )

    @classmethod
    def of_runs(cls, runs: int, steps: int, every: int, bodies: int) -> Work:
        """`runs` runs of `steps` steps each, logging every `every`-th step of `bodies` bodies."""
        rows = math.ceil(steps / every)
        per_row = LOG_BYTES_PER_ROW + LOG_BYTES_PER_BODY_ROW * bodies
        fixed = LOG_BYTES_PER_LOG + LOG_BYTES_PER_BODY * bodies
        return cls(runs, runs * steps, steps, runs * (fixed + rows * per_row))

    def describe(self) -> str:
        """One phrase for people: runs, steps, log size and simulation time (estimates)."""
        hours = self.steps * US_PER_STEP / 1e6 / 3600
        if not self.steps:  # not estimated: refused on the number of runs alone
            return f"{self.runs:,} run(s)"
        return (
            f"{self.runs:,} run(s), up to {self.steps:.3g} steps (longest run "
            f"{self.longest_run_steps:.3g}), about {_size(self.log_bytes)} of logs and "
            f"{_duration(hours)} of simulation"
        )


class WorkError(ImpactlabError):
    """A job asks for more than the limits allow (not allowed explicitly). Exit code 2."""

    exit_code = 2


def problems(work: Work) -> list[str]:
    """What exceeds a limit (empty when the job is within every limit)."""
    found = []
    if work.runs > MAX_RUNS:
        found.append(f"{work.runs:,} runs > {MAX_RUNS:,}")
    if work.longest_run_steps > MAX_RUN_STEPS:
        found.append(f"a run of {work.longest_run_steps:.3g} steps > {MAX_RUN_STEPS:.3g}")
    if work.steps > MAX_JOB_STEPS:
        found.append(f"{work.steps:.3g} steps in the job > {MAX_JOB_STEPS:.3g}")
    if work.log_bytes > MAX_LOG_BYTES:
        found.append(f"about {_size(work.log_bytes)} of logs > {_size(MAX_LOG_BYTES)}")
    return found


def check_work(work: Work, *, source: str, allow_large: bool) -> None:
    """Refuse a job beyond the limits, naming what is too much, unless `allow_large`.

    Raises:
        WorkError: one line: the source, what is too much, the estimate and how to go ahead.
    """
    found = problems(work)
    if found and not allow_large:
        raise WorkError(
            f"{source}: too much work: {'; '.join(found)} ({work.describe()}); check the "
            f"timestep, time limit and sweep, or pass {ALLOW_FLAG} to record it anyway"
        )


def check_space(work: Work, out_dir: Path, *, allow_large: bool) -> None:
    """Refuse logs estimated larger than the free space in `out_dir` (a folder that exists),
    unless `allow_large`.

    Raises:
        WorkError: one line naming the folder, the estimate and the free space.
    """
    try:
        free = shutil.disk_usage(out_dir).free
    except OSError:
        return
    if work.log_bytes > free and not allow_large:
        raise WorkError(
            f"{out_dir}: not enough space: about {_size(work.log_bytes)} of logs to write, "
            f"{_size(free)} free; free some, or pass {ALLOW_FLAG} to record anyway"
        )


def _size(n: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n / 1e3:.3g} kB"


def _duration(hours: float) -> str:
    if hours >= 48:
        return f"{hours / 24:.3g} days"
    if hours >= 1:
        return f"{hours:.3g} hours"
    return f"{hours * 60:.2g} minutes"
