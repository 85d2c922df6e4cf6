"""Record: experiment specs or MJCF models -> MuJoCo runs -> one MCAP log per run.

Owns: the spec's declared schema (`schema`), experiment specs and sweeps (`spec`, `sweep`),
an MJCF model's run options (`mjcf_options`), the instrumented MuJoCo models (`model`,
`geometry`, `contact_pairs`), the simulation streamed chunk by chunk with its stop rules
and MuJoCo's warnings (`simulate`, `stop`, `mujoco_warnings`), and the record job (`planner`
plans, keeping a sweep as its grid (`PlannedRuns`), `work` estimates and refuses absurd jobs,
`recorder` runs here or as executor tasks).

May import: `impactlab.logs` (to write logs), `impactlab.contact`, `impactlab.mjcf`,
`impactlab.executors`, MuJoCo. Must not import: `impactlab.analyze`, `impactlab.replay`,
`impactlab.calibrate`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from impactlab.packages import lazy_exports

if TYPE_CHECKING:
    from impactlab.executors.base import Executor
    from impactlab.progress import Progress
    from impactlab.record.contact_pairs import calibrated_pairs as calibrated_pairs
    from impactlab.record.planner import PlannedRun as PlannedRun
    from impactlab.record.recorder import record_runs as record_runs
    from impactlab.record.results import RecordedRun as RecordedRun
    from impactlab.record.results import RecordResult as RecordResult

Inputs = str | Path | Mapping[str, Any] | Sequence[Any]

if not TYPE_CHECKING:  # a type checker sees the imports above
    __getattr__ = lazy_exports(
        __name__,
        {
            "PlannedRun": "impactlab.record.planner",
            "RecordedRun": "impactlab.record.results",
            "RecordResult": "impactlab.record.results",
            "calibrated_pairs": "impactlab.record.contact_pairs",
            "record_runs": "impactlab.record.recorder",
        },
    )


def _items(inputs: Inputs) -> list[Any]:
    if isinstance(inputs, str | Path | Mapping):
        return [inputs]
    return list(inputs)


def plan(
    inputs: Inputs,
    *,
    overrides: Sequence[str] = (),
    duration: float | None = None,
    allow_large: bool = False,
) -> Sequence[PlannedRun]:
    """Validate specs or models and return the runs they give, without simulating.

    The runs are a sequence (`len`, indexing, iteration) that builds a sweep's run when it
    is read, so a large sweep is planned in little memory; `list(...)` holds them all.

    Args:
        inputs: a spec file (.toml), an MJCF model (.xml), a spec document (a dict with the
            TOML file's content), or a list of them.
        overrides: `PATH=VALUE` settings (VALUE is TOML), e.g. `"ball.mass=2"`.
        duration: time limit in s for MJCF models.
        allow_large: plan a job beyond the work limits (`impactlab.record.work`).

    Raises:
        SpecError: an input, override or option is wrong (the message names it).
        WorkError: the job is beyond the work limits (and not `allow_large`).
    """
    from impactlab.record.planner import plan as plan_runs

    return plan_runs(
        _items(inputs), overrides=overrides, duration=duration, allow_large=allow_large
    )


def record(
    inputs: Inputs,
    *,
    out: str | Path = "logs",
    overrides: Sequence[str] = (),
    duration: float | None = None,
    overwrite: bool = False,
    allow_large: bool = False,
    executor: Executor | str | None = None,
    progress: Progress | None = None,
    verbose: bool = False,
) -> RecordResult:
    """Simulate every run of specs or models and write one MCAP log per run into `out`.

    Runs whose complete log is in `out` already are reused (and returned, status "reused").

    Args:
        inputs: what `plan` takes, or runs `plan` returned.
        out: the output folder (created).
        overrides, duration: as for `plan`.
        overwrite: record again runs whose complete log exists.
        allow_large: record a job beyond the work limits (`impactlab.record.work`).
        executor: "local" (default), "ray", or an `impactlab.executors` executor.
        progress: called with each `impactlab.progress.ProgressEvent`; None: silent.
        verbose: report progress on the console (when `progress` is None).

    Returns:
        Every run with its log path, status and outcome, in plan order.

    Raises:
        SpecError: an input is wrong (nothing is simulated).
        WorkError: the job is beyond the work limits (nothing is simulated).
        OutputError: `out` cannot be written.
    """
    from impactlab.executors.choose import executor_for
    from impactlab.files import OutputError
    from impactlab.progress import reporter
    from impactlab.record.planner import PlannedRun, PlannedRuns
    from impactlab.record.recorder import record_runs

    if not str(out).strip():
        raise OutputError(str(out), "the output folder must not be empty (for this folder: '.')")
    items = [] if isinstance(inputs, PlannedRuns) else _items(inputs)
    runs: Sequence[PlannedRun] = items
    if isinstance(inputs, PlannedRuns):
        runs = inputs
    elif not items or not all(isinstance(r, PlannedRun) for r in items):
        runs = plan(items, overrides=overrides, duration=duration, allow_large=allow_large)
    with executor_for(executor) as chosen, reporter(progress, verbose) as shown:
        return record_runs(
            runs,
            Path(out),
            executor=chosen,
            overwrite=overwrite,
            allow_large=allow_large,
            progress=shown,
        )
