"""Run options of an MJCF model: a spec's `[stop]` and `[logging]`, a keyframe, nothing else."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from pydantic import ValidationError

from impactlab.errors import SpecError
from impactlab.record.model import InstrumentedModel
from impactlab.record.schema import MAX_TIME_S, SECTIONS, MjcfRunOptions, Stop, defaults
from impactlab.record.spec import schema_error, set_path
from impactlab.record.sweep import parse_override

MJCF_SECTIONS = ("stop", "logging")
MJCF_KEYS = ("keyframe",)  # run options outside the sections


@dataclass(frozen=True)
class MjcfOptions:
    """An MJCF run's stop rules, logging stride and the resolved tables (for its log)."""

    stop: Stop
    log_every: int
    document: dict[str, Any]
    keyframe: str | None = None


def mjcf_options(source: str, overrides: Sequence[str], duration: float | None) -> MjcfOptions:
    """The run options of an MJCF model from `--set` overrides and `--duration`, validated
    against the schema's `MjcfRunOptions`.

    Raises:
        SpecError: an override names anything but stop.* or logging.*, a value is wrong,
            or no time limit is given.
    """
    doc: dict[str, Any] = {section: defaults(SECTIONS[section]) for section in MJCF_SECTIONS}
    doc["stop"]["max_time"] = None
    for text in overrides:
        key, value = parse_override(text)
        if key.split(".")[0] not in MJCF_SECTIONS and key not in MJCF_KEYS:
            raise SpecError(
                source,
                f"--set {key}",
                "an MJCF model takes run options only (stop.*, logging.*, keyframe); "
                "change the model itself for anything else",
            )
        if key in MJCF_KEYS:
            doc[key] = value
        else:
            set_path(doc, key, value, source)
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
    try:
        options = MjcfRunOptions.model_validate(doc)
    except ValidationError as exc:
        raise schema_error(exc, source) from None
    return MjcfOptions(options.stop, options.logging.every, doc, options.keyframe)


def check_options(options: MjcfOptions, inst: InstrumentedModel, source: str) -> None:
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
