"""Plan a record job: specs or MJCF files -> validated runs, each built when it is read."""

from __future__ import annotations

import bisect
import functools
import re
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar, overload

from impactlab.errors import SpecError
from impactlab.files import NOT_TEXT, is_text
from impactlab.logs.metadata import PairTarget
from impactlab.record.contact_pairs import CalibratedPair, calibrated_pairs
from impactlab.record.log_rows import RunInfo, refuse_unreadable
from impactlab.record.mjcf_options import check_options, mjcf_options
from impactlab.record.model import InstrumentedModel, model_from_mjcf, model_from_spec
from impactlab.record.model_files import model_digest
from impactlab.record.spec import RunSpec, Stop, spec_hash
from impactlab.record.sweep import SpecSweep
from impactlab.record.work import Work, check_work, run_steps

MJCF_SUFFIXES = (".xml", ".mjcf")
DOCUMENT_SOURCE = "<python>"  # the source of a spec given as a dict
MAX_READABLE_NAME = 160  # characters of a log's name before its hash


@dataclass(frozen=True)
class PlannedRun:
    """A run ready to simulate: its file name, metadata and how to build and stop it.

    `spec` is the resolved spec (None for an MJCF model); `stop` the run's stop rules;
    `pairs` the spec's calibrated contacts, computed once when it is planned (`build` and
    the log's `contact_targets` take them from here).
    """

    info: RunInfo
    build: Callable[[], InstrumentedModel] = field(compare=False)
    spec: RunSpec | None
    stop: Stop
    work: Work = field(default_factory=Work)  # at most (`impactlab.record.work`)
    pairs: tuple[CalibratedPair, ...] = ()

    @property
    def max_time(self) -> float:
        """The run's time limit, s."""
        return self.stop.max_time


def plan(
    inputs: Sequence[str | Path | Mapping[str, Any]],
    *,
    overrides: Sequence[str] = (),
    duration: float | None = None,
    allow_large: bool = False,
) -> PlannedRuns:
    """Validate every input and return the runs to record, in order.

    The job's work is estimated first, from the specs' sweeps without expanding them
    (`impactlab.record.work`): a job beyond the limits is refused unless `allow_large`.
    Every run is validated here; a sweep's runs are not kept but built again when read
    (`impactlab.record.planner.PlannedRuns`), so a large sweep plans in little memory.

    Args:
        inputs: experiment specs (.toml files, or spec documents as dicts) and/or MJCF
            models (.xml).
        overrides: `PATH=VALUE` settings: any field of a spec; for MJCF models the run
            options only (`stop.*`, `logging.*`).
        duration: time limit in s for MJCF models (or `stop.max_time=...`).
        allow_large: plan a job beyond the limits of `impactlab.record.work`.

    Raises:
        SpecError: any input, override or option is wrong.
        WorkError: the job is beyond the limits (and not `allow_large`).
    """
    parts: list[SpecSweep | PlannedRun] = []
    for item in inputs:
        if isinstance(item, Mapping):
            parts.append(SpecSweep.of(item, DOCUMENT_SOURCE, overrides))
            continue
        path = Path(item)
        if not is_text(path):  # its path goes into the log
            raise SpecError(str(path), "", NOT_TEXT)
        if path.suffix.lower() in MJCF_SUFFIXES:
            parts.append(_plan_mjcf(path, overrides=overrides, duration=duration))
        elif path.suffix.lower() == ".toml":
            if duration is not None:
                raise SpecError(
                    str(path),
                    "--duration",
                    "applies to MJCF models; for specs use --set stop.max_time=...",
                )
            parts.append(SpecSweep.read(path, overrides))
        else:
            raise SpecError(
                str(path), "", "expected an experiment spec (.toml) or an MJCF model (.xml)"
            )
    work = sum((_work(part) for part in parts), Work())
    sources = [p.source if isinstance(p, SpecSweep) else p.info.source for p in parts]
    check_work(work, source=", ".join(dict.fromkeys(sources)), allow_large=allow_large)
    runs = PlannedRuns(parts)
    first: dict[str, int] = {}  # every run is validated now, then dropped: built again when run
    for index, run in enumerate(runs):
        if run.spec is not None and run.info.sweep_index == 0:
            refuse_unreadable(run.build(), run.info)  # MuJoCo's checks and the log's, now
        other = first.setdefault(run.info.run_id, index)
        if other != index:
            where = f"sweep point {_point(run)}" if run.info.sweep else "its only run"
            raise SpecError(
                run.info.source,
                "",
                f"{where} is the same run as {_point(runs[other])} of "
                f"{runs[other].info.source}; give each input once",
            )
    return runs


def _work(part: SpecSweep | PlannedRun) -> Work:
    if isinstance(part, SpecSweep):
        return part.work()
    return part.work


def _point(run: PlannedRun) -> str:
    values = ", ".join(f"{k} = {v}" for k, v in run.info.sweep.items())
    return f"({values})" if values else "the run"


def _plan_spec(run: RunSpec) -> PlannedRun:
    pairs = tuple(calibrated_pairs(run))  # contact targets fail now, before any simulation
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
        contact_targets=tuple(_target(p) for p in pairs),
        separation_m=run.stop.separation,
    )
    steps = run_steps(run.stop.max_time, run.options.timestep)
    work = Work.of_runs(1, steps, run.log_every, len(run.bodies))
    build = functools.partial(model_from_spec, run, pairs)
    return PlannedRun(info, build, run, run.stop, work, pairs)


def _target(pair: CalibratedPair) -> PairTarget:
    """What the log says of a calibrated pair: its target (with an e(v), the curve's points)."""
    p, curve = pair.params, pair.params.curve
    points = (curve.speed_mps, curve.e) if curve is not None else (None, None)
    return PairTarget(pair.geom1, pair.geom2, p.restitution, p.speed_range_mps, *points)


def _plan_mjcf(path: Path, *, overrides: Sequence[str], duration: float | None) -> PlannedRun:
    options, settings = mjcf_options(str(path), overrides, duration)
    gaps = options.stop.separation is not None
    inst = model_from_mjcf(path, keyframe=options.keyframe, gaps=gaps)
    check_options(options, inst, str(path))
    # the model by name and content as MuJoCo compiled it (every file it read), not by where
    # it is: the same model gives the same run, a change in any of its files another
    document: dict[str, Any] = {
        "mjcf": path.name,
        "model_sha256": model_digest(inst.model, inst.attachments),
    }
    document |= settings
    digest = spec_hash(document)
    info = RunInfo(
        run_id=run_name(path.stem, {}, digest),
        experiment=path.stem,
        description=f"user model {path.name}",
        source=str(path),
        spec=document,
        sweep={},
        spec_hash=digest,
        log_every=options.logging.every,
        separation_m=options.stop.separation,
    )
    refuse_unreadable(inst, info)
    steps = run_steps(options.stop.max_time, float(inst.model.opt.timestep))
    work = Work.of_runs(1, steps, options.logging.every, len(inst.bodies))
    return PlannedRun(info, lambda: inst, None, options.stop, work)


def run_name(experiment: str, sweep_values: dict[str, Any] | Any, digest: str) -> str:
    """A readable, unique file stem: experiment, sweep values, first 8 hex of the spec hash."""
    parts = [experiment]
    for key, value in sweep_values.items():
        leaf = key.removeprefix("bodies.").removeprefix("contact.").removeprefix("options.")
        text = "_".join(f"{v:g}" for v in value) if isinstance(value, list) else str(value)
        parts.append(f"{leaf}={text}")
    readable = re.sub(r"[^A-Za-z0-9._=+-]", "_", "-".join(parts))
    if len(readable) > MAX_READABLE_NAME:  # file names have at most 255 bytes
        readable = readable[: MAX_READABLE_NAME - 3] + "..."
    return f"{readable}-{digest[:8]}"


class PlannedRuns(Sequence[PlannedRun]):
    """The runs of a job's inputs, in plan order, each built when it is read (`parts`: per
    input, its sweep, checked already, or its one planned run)."""

    def __init__(self, parts: Sequence[SpecSweep | PlannedRun]) -> None:
        self._parts = list(parts)
        self._starts: list[int] = []
        total = 0
        for part in self._parts:
            self._starts.append(total)
            total += len(part) if isinstance(part, SpecSweep) else 1
        self._len = total

    def __len__(self) -> int:
        return self._len

    @overload
    def __getitem__(self, index: int) -> PlannedRun: ...
    @overload
    def __getitem__(self, index: slice) -> list[PlannedRun]: ...
    def __getitem__(self, index: int | slice) -> PlannedRun | list[PlannedRun]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(self._len))]
        if index < 0:
            index += self._len
        if not 0 <= index < self._len:
            raise IndexError(f"run {index} of {self._len}")
        at = bisect.bisect_right(self._starts, index) - 1
        part = self._parts[at]
        if isinstance(part, SpecSweep):
            return _plan_spec(part.run(index - self._starts[at]))
        return part

    def __iter__(self) -> Iterator[PlannedRun]:
        for part in self._parts:
            if isinstance(part, SpecSweep):
                yield from map(_plan_spec, part.iter_runs())
            else:
                yield part

    def __repr__(self) -> str:
        return f"PlannedRuns({self._len} runs)"


T = TypeVar("T")  # a planned run (`PlannedRun`)


class Subset(Sequence[T]):
    """Some runs of a sequence, by index, read from it when asked for."""

    def __init__(self, runs: Sequence[T], indices: Sequence[int]) -> None:
        self._runs, self._indices = runs, indices

    def __len__(self) -> int:
        return len(self._indices)

    @overload
    def __getitem__(self, index: int) -> T: ...
    @overload
    def __getitem__(self, index: slice) -> Subset[T]: ...
    def __getitem__(self, index: int | slice) -> T | Subset[T]:
        if isinstance(index, slice):
            return Subset(self._runs, self._indices[index])
        return self._runs[self._indices[index]]

    def __iter__(self) -> Iterator[T]:
        for i in self._indices:
            yield self._runs[i]
