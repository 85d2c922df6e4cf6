"""Run options of an MJCF model: a spec's `[stop]` and `[logging]`, a keyframe, nothing else."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from impactlab.errors import SpecError
from impactlab.record.model import InstrumentedModel
from impactlab.record.schema import MAX_TIME_S, Logging, MjcfRunOptions, Stop, defaults
from impactlab.record.spec import checked, set_path
from impactlab.record.sweep import parse_override


def mjcf_options(
    source: str, overrides: Sequence[str], duration: float | None
) -> tuple[MjcfRunOptions, dict[str, Any]]:
    """The run options of an MJCF model from `--set` overrides and `--duration`, validated,
    and the document they were validated from (the run's log keeps it).

    Raises:
        SpecError: an override names anything but a run option, a value is wrong,
            or no time limit is given.
    """
    doc: dict[str, Any] = {
        "stop": {**defaults(Stop), "max_time": None},
        "logging": defaults(Logging),
    }
    for text in overrides:
        key, value = parse_override(text)
        if key.split(".")[0] not in MjcfRunOptions.model_fields:
            raise SpecError(
                source,
                f"--set {key}",
                "an MJCF model takes run options only (stop.*, logging.*, keyframe); "
                "change the model itself for anything else",
            )
        set_path(doc, key, value, source, MjcfRunOptions)
    if duration is not None:
        if not 0 < duration <= MAX_TIME_S:
            raise SpecError(
                source,
                "--duration",
                f"an MJCF model needs --duration SECONDS, > 0 and <= {MAX_TIME_S:g}, "
                f"got {duration}",
            )
        if doc["stop"]["max_time"] is not None:
            raise SpecError(source, "--duration", "give --duration or stop.max_time, not both")
        doc["stop"]["max_time"] = duration
    if doc["stop"]["max_time"] is None:
        raise SpecError(
            source, "--duration", "an MJCF model needs --duration SECONDS (or stop.max_time)"
        )
    return checked(MjcfRunOptions, doc, source), doc


def check_options(options: MjcfRunOptions, inst: InstrumentedModel, source: str) -> None:
    """Reject stop rules the model cannot meet (as `spec` does for a spec's own model).

    Raises:
        SpecError: naming the option and why.
    """
    stop = options.stop
    timestep = float(inst.model.opt.timestep)
    if stop.bounces is not None and not inst.surfaces:
        raise SpecError(
            source,
            "stop.bounces",
            "counts bounces on the ground, but no static geom of the model can be landed on",
        )
    if stop.separation is not None and len(inst.bodies) < 2:
        raise SpecError(source, "stop.separation", "a collision needs at least two free bodies")
    if timestep >= stop.max_time:
        raise SpecError(
            source,
            "stop.max_time",
            f"{stop.max_time} s is not longer than the model's timestep {timestep} s",
        )
