"""A log's metadata records as declared models: the recorder builds them, `checks` reads them."""

from __future__ import annotations

import functools
import itertools
import json
from collections.abc import Mapping, Sequence
from typing import Annotated, Any

from pydantic import AfterValidator, Field, TypeAdapter
from pydantic.dataclasses import dataclass

from impactlab.logs import format as logformat
from impactlab.physics import INTEGRATORS, half_step_s
from impactlab.version import __version__

BIG = 1e6  # |gravity| m/s^2, |plane_z|, levels, sizes, speeds and separations in m and m/s
ANALYSIS_KEYS = (
    "timestep_s",
    "log_every",
    "bodies",
    "gravity",
    "plane_z",
    "integrator",
    "ground",
    "static_potential_J",
    "half_step_s",
)
"""The keys without which no energy, height or restitution of a run can be trusted."""

Number = Annotated[float, Field(strict=True, allow_inf_nan=False)]
Whole = Annotated[int, Field(strict=True, ge=0, le=10**15)]
Text = Annotated[str, Field(strict=True)]
Name = Annotated[str, Field(strict=True, min_length=1)]
Within = Annotated[Number, Field(ge=-BIG, le=BIG)]
Positive = Annotated[Number, Field(gt=0, le=BIG)]
Inertia = Annotated[Number, Field(ge=0, le=1e12)]


@functools.cache
def adapter(kind: Any) -> TypeAdapter[Any]:
    """The validator and serializer of a type, built once (building one takes milliseconds)."""
    return TypeAdapter(kind)


def valid_if(test: Any, problem: str) -> AfterValidator:
    """A validator that refuses a value for which `test` is false, saying `problem`."""

    def check(value: Any) -> Any:
        if not test(value):
            raise ValueError(problem)
        return value

    return AfterValidator(check)


def one_of(*names: str) -> AfterValidator:
    return valid_if(lambda v: v in names, f"is not one of {', '.join(names)}")


@dataclass(frozen=True)
class Body:
    """A moving body: mass kg, principal inertia kg m^2, radius m (one sphere centred at its
    centre of mass, else None), its collision geoms' types (`shape`) and names, the lowest
    height of its centre of mass over a flat surface it touches, and "free" or "articulated"."""

    name: Name
    mass: Annotated[Number, Field(gt=0, le=1e9)]
    inertia: tuple[Inertia, Inertia, Inertia]
    radius: Positive | None = None
    shape: Text = ""
    rest_height_m: Within | None = None
    geoms: Sequence[Text] = ()
    motion: Annotated[str, one_of("free", "articulated")] = "free"  # written unless free


@dataclass(frozen=True)
class Surface:
    """A static geom free bodies can land on: its highest point along -gravity (a plane: its
    origin), m; `distance`: MuJoCo measures the distance to it."""

    name: Text
    type: Text
    level_m: Number
    distance: Annotated[bool, Field(strict=True)] = True


Restitution = Annotated[Number, Field(ge=0, le=1)]


def _curve(target: PairTarget) -> bool:
    xs, es = target.curve_speed_mps, target.curve_e
    if xs is None or es is None:
        return xs is es
    return 2 <= len(xs) == len(es) <= 64 and all(a < b for a, b in itertools.pairwise(xs))


@dataclass(frozen=True)
class PairTarget:
    """A geom pair calibrated to a target restitution over normal impact speeds (lo, hi) m/s
    (None: a format-1 log that does not say); a target e(v) is the curve through the points
    (`curve_speed_mps` ascending, m/s; `curve_e`), piecewise linear, none outside them
    (`impactlab.physics.restitution_on_curve`); None: the constant `restitution`."""

    geom1: Name
    geom2: Name
    restitution: Restitution
    speed_range_mps: Annotated[
        tuple[Positive, Positive] | None, valid_if(lambda s: s is None or s[0] <= s[1], "lo > hi")
    ]
    curve_speed_mps: tuple[Positive, ...] | None = None
    curve_e: tuple[Restitution, ...] | None = None

    def __post_init__(self) -> None:
        if not _curve(self):
            raise ValueError(
                "curve_speed_mps (ascending) and curve_e: both or neither, 2 to 64 points each"
            )

    @property
    def pair(self) -> str:
        """The pair as specs and tables name it: "geom1/geom2"."""
        return f"{self.geom1}/{self.geom2}"


@dataclass(frozen=True)
class GeomContact:
    """MuJoCo's solref (2) and solimp (3 to 5) every geom of the model shares."""

    solref: Annotated[tuple[Number, ...], Field(min_length=2, max_length=2)]
    solimp: Annotated[tuple[Number, ...], Field(min_length=3, max_length=5)]


def _spec(spec: dict[str, Any]) -> bool:
    bodies = spec.get("bodies", {})
    sections = ("contact", "options", "plane", "stop", "logging")
    return (
        isinstance(bodies, dict)
        and all(isinstance(b, dict) for b in bodies.values())
        and all(isinstance(spec.get(name, {}), dict | None) for name in sections)
    )


@dataclass(frozen=True)
class RunMeta:
    """The `impactlab.run` record (`format.RUN_KEYS` says what each key holds)."""

    experiment: Text
    description: Text
    source: Text
    run_id: Annotated[str, Field(strict=True, pattern=r"\S")]
    spec: Annotated[Mapping[str, Any], valid_if(_spec, "its bodies or sections are not tables")]
    sweep: Mapping[str, Any]
    spec_hash: Text
    timestep_s: Annotated[Number, Field(ge=1e-9, le=10)]
    log_every: Annotated[Whole, Field(ge=1, le=10**9)]
    gravity: tuple[Within, Within, Within]
    bodies: Annotated[
        Sequence[Body], valid_if(lambda b: len({x.name for x in b}) == len(b), "a name twice")
    ]
    plane_z: Within | None
    mujoco_version: Text
    sweep_index: Whole = 0
    sweep_size: Annotated[Whole, Field(ge=1)] = 1
    integrator: Annotated[str, one_of(*INTEGRATORS)] = "Euler"
    ground: Annotated[
        Sequence[Surface], valid_if(lambda g: all(abs(s.level_m) <= BIG for s in g), "a level")
    ] = ()
    static_potential_J: Annotated[Number, Field(ge=-1e15, le=1e15)] = 0.0
    contact_targets: Sequence[PairTarget] = ()
    geom_contact: GeomContact | None = None
    separation_m: Positive | None = None
    half_step_s: Annotated[Number, Field(ge=0, le=5)] = 0.0  # written: the integrator's (`record`)
    log_format_version: Annotated[str, one_of(*logformat.READABLE_FORMATS)] = (
        logformat.LOG_FORMAT_VERSION
    )
    impactlab_version: Text = __version__

    def record(self) -> dict[str, str]:
        """The record as written, every value a string."""
        half = half_step_s(self.integrator, self.timestep_s)
        return _store(self, logformat.RUN_KEYS) | {"half_step_s": repr(half)}


@dataclass(frozen=True)
class Outcome:
    """The `impactlab.outcome` record: how the run ended (also the /events messages)."""

    outcome: Annotated[str, one_of("completed", "unstable")]
    reason: Text
    steps: Whole
    warnings: Sequence[Text] = ()

    def record(self) -> dict[str, str]:
        """The record as written, every value a string."""
        return _store(self, logformat.OUTCOME_KEYS)


def _store(record: RunMeta | Outcome, keys: Mapping[str, str]) -> dict[str, str]:
    """Each key's value as stored: text as is, none as "", anything else as JSON."""
    kind: Any = type(record)
    dumped = adapter(kind).dump_python(record, mode="json")
    if "bodies" in dumped:  # a free body's motion is not written (logs before it had none)
        dumped["bodies"] = [
            {k: v for k, v in b.items() if (k, v) != ("motion", "free")} for b in dumped["bodies"]
        ]
    if "contact_targets" in dumped:  # a constant target is written as before curves existed
        dumped["contact_targets"] = [
            {k: v for k, v in t.items() if not (k.startswith("curve_") and v is None)}
            for t in dumped["contact_targets"]
        ]

    def stored(k: str, v: Any) -> str:
        return (
            v if isinstance(v, str) else "" if v is None else json.dumps(v, sort_keys=k in SORTED)
        )

    return {k: stored(k, dumped[k]) for k in keys}


RECORDS = {logformat.RUN_METADATA: RunMeta, logformat.OUTCOME_METADATA: Outcome}
HOLDS = logformat.RUN_KEYS | logformat.OUTCOME_KEYS
"""What each key of the two records holds (docs/log-format.md's table)."""
TEXT = {k for k, holds in HOLDS.items() if not holds.startswith(("JSON", "number", "whole"))}
"""The keys stored as text as it is; the others are JSON, "" for none."""
SORTED = ("spec", "sweep")  # JSON objects stored with their keys sorted
