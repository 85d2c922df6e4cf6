"""Plan a record job: specs or MJCF files -> validated runs, each with its name and metadata.

Everything is validated before the first simulation, so a wrong input writes nothing.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from impactlab.errors import SpecError
from impactlab.record.contact_pairs import calibrated_pairs
from impactlab.record.log_rows import RunInfo
from impactlab.record.mjcf_options import check_options, mjcf_options
from impactlab.record.model import InstrumentedModel, model_from_mjcf, model_from_spec
from impactlab.record.spec import RunSpec, Stop, spec_hash
from impactlab.record.sweep import document_runs, load_runs

MJCF_SUFFIXES = (".xml", ".mjcf")
DOCUMENT_SOURCE = "<python>"  # the source of a spec given as a dict


@dataclass(frozen=True)
class PlannedRun:
    """A run ready to simulate: its file name, metadata and how to build and stop it.

    `spec` is the resolved spec (None for an MJCF model); `stop` the run's stop rules.
    """

    info: RunInfo
    build: Callable[[], InstrumentedModel]
    spec: RunSpec | None
    max_time: float
    stop: Stop | None = None


def plan(
    inputs: Sequence[str | Path | Mapping[str, Any]],
    *,
    overrides: Sequence[str] = (),
    duration: float | None = None,
) -> list[PlannedRun]:
    """Validate every input and return the runs to record, in order.

    Args:
        inputs: experiment specs (.toml files, or spec documents as dicts) and/or MJCF
            models (.xml).
        overrides: `PATH=VALUE` settings: any field of a spec; for MJCF models the run
            options only (`stop.*`, `logging.*`).
        duration: time limit in s for MJCF models (or `stop.max_time=...`).

    Raises:
        SpecError: any input, override or option is wrong.
    """
    runs: list[PlannedRun] = []
    for item in inputs:
        if isinstance(item, Mapping):
            runs += [_plan_spec(run) for run in document_runs(item, DOCUMENT_SOURCE, overrides)]
            continue
        path = Path(item)
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
    return PlannedRun(info, lambda: model_from_spec(run), run, run.stop.max_time, run.stop)


def _plan_mjcf(path: Path, *, overrides: Sequence[str], duration: float | None) -> PlannedRun:
    options = mjcf_options(str(path), overrides, duration)
    inst = model_from_mjcf(path)  # validate now; rebuilt when run
    check_options(options, inst, str(path))
    # the model by name and content, not by where it is: the same model gives the same run
    document = {"mjcf": path.name, "xml_sha256": _sha256(inst.xml), **options.document}
    digest = spec_hash(document)
    info = RunInfo(
        run_id=run_name(path.stem, {}, digest),
        experiment=path.stem,
        description=f"user model {path.name}",
        source=str(path),
        spec=document,
        sweep={},
        spec_hash=digest,
        log_every=options.log_every,
    )
    return PlannedRun(info, lambda: inst, None, options.stop.max_time, options.stop)


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
