"""The experiment spec's schema: each field's type, range, unit and default, declared once."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Annotated, Any

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PlainValidator,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from impactlab.contact.closed_form import ContactModelError
from impactlab.contact.curve import RestitutionCurve
from impactlab.logs.checks import PLANE_GEOM
from impactlab.physics import Integrator
from impactlab.text import clipped

CONDIMS = (1, 3, 4, 6)
MIN_TIMESTEP_S = 1e-9  # log times are whole nanoseconds
MAX_TIME_S = 1e9  # log times are int64 nanoseconds (2^63 ns is 292 years)
MAX_LOG_EVERY = 1_000_000_000
MAX_NAME_LENGTH = 64
MAX_BODIES = 64
RESERVED_BODY_NAMES = {
    "world": "MuJoCo's world body",
    PLANE_GEOM: 'the ground plane\'s name (contact pairs such as "ball/plane")',
}
MUJOCO_MINVAL = 1e-15  # mjMINVAL: MuJoCo refuses lighter moving bodies


def problem(text: str, field: str = "") -> PydanticCustomError:
    """A validation error with our own wording; `field` (dotted, from the section validated)
    names the field it is about when that is not the value being validated."""
    return PydanticCustomError("impactlab", "{text}", {"text": text, "field": field})


def unit(symbol: str, *, filled: bool = True) -> Any:
    """The unit of a field, kept in its schema (JSON schema key `unit`); `filled=False`: a
    field added after specs were hashed, left out of a document that does not give it (every
    older spec keeps its hash, see `defaults`)."""
    return Field(json_schema_extra={"unit": symbol, "filled": filled})


Number = Annotated[float, Field(strict=True, allow_inf_nan=False)]  # strict: true is no number
Positive = Annotated[Number, Field(gt=0)]
NonNegative = Annotated[Number, Field(ge=0)]
Fraction = Annotated[Number, Field(ge=0, le=1)]
Integer = Annotated[int, Field(strict=True)]
Flag = Annotated[bool, Field(strict=True)]


def _name(value: str) -> str:
    if not value or not value.replace("_", "a").isalnum() or len(value) > MAX_NAME_LENGTH:
        raise problem(
            f"must be a name of 1 to {MAX_NAME_LENGTH} letters, digits and _, got {short(value)}"
        )
    return value


Name = Annotated[str, Field(strict=True), AfterValidator(_name)]


def _vector(lengths: tuple[int, ...]) -> BeforeValidator:
    want = " or ".join(str(n) for n in lengths)

    def check(value: Any) -> Any:
        if not isinstance(value, list | tuple) or len(value) not in lengths:
            raise problem(f"must be a list of {want} numbers, got {short(value)}")
        return value

    return BeforeValidator(check)


# Lists of numbers of one of the given lengths (TOML arrays), validated item by item.
Vector2 = Annotated[tuple[Number, ...], _vector((2,))]
Vector3 = Annotated[tuple[Number, ...], _vector((3,))]
Vector3or5 = Annotated[tuple[Number, ...], _vector((3, 5))]
NonNegative3 = Annotated[tuple[NonNegative, ...], _vector((3,))]
Rgba = Annotated[tuple[Fraction, ...], _vector((4,))]


def short(value: Any, limit: int = 60) -> str:
    """`repr(value)` cut to `limit` characters (a huge or deeply nested value stays readable)."""
    return clipped(repr(value), limit)


class Section(BaseModel):
    """A table of the spec: unknown keys are errors, values are checked strictly (no "1" for
    1), a validated section is frozen; its validator is built on first use (`defer_build`)."""

    model_config = ConfigDict(
        extra="forbid", frozen=True, hide_input_in_errors=True, defer_build=True
    )


class Options(Section):
    """Simulation options."""

    timestep: Annotated[Positive, unit("s")] = 0.002
    integrator: Integrator = "Euler"
    gravity: Annotated[Vector3, unit("m/s^2")] = (0.0, 0.0, -9.81)

    @model_validator(mode="after")
    def _resolvable(self) -> Options:
        if self.timestep < MIN_TIMESTEP_S:
            raise problem(
                f"must be >= {MIN_TIMESTEP_S:g} s (log times are whole nanoseconds), "
                f"got {self.timestep!r}",
                "timestep",
            )
        return self


def _speed_range(value: tuple[float, ...]) -> tuple[float, ...]:
    if not 0.0 < value[0] <= value[1]:
        raise problem(f"need 0 < v_lo <= v_hi (m/s), got {list(value)}")
    return value


SpeedRange = Annotated[Vector2, AfterValidator(_speed_range), unit("m/s")]


CURVE_KEYS = ("speed_mps", "e")


def _restitution(value: Any) -> float | RestitutionCurve:
    """A target e: a number, or a table of measured points `{speed_mps = [...], e = [...]}`
    (a `RestitutionCurve`, checked by its own rules)."""
    if isinstance(value, RestitutionCurve):
        return value
    if isinstance(value, Mapping):
        shape = "a curve is {speed_mps = [...], e = [...]}"
        unknown = [k for k in value if k not in CURVE_KEYS]
        if unknown:
            raise problem(f"unknown key: {shape}", clipped(str(unknown[0]), 60))
        if len(value) != len(CURVE_KEYS):
            raise problem(f"needs both speed_mps and e: {shape}")
        for key in CURVE_KEYS:
            items = value[key]
            if not isinstance(items, list | tuple) or not all(_finite(x) for x in items):
                raise problem(f"must be a list of finite numbers, got {short(items)}", key)
        try:
            return RestitutionCurve.of(value["speed_mps"], value["e"])
        except ContactModelError as exc:
            raise problem(str(exc)) from None
    if not _finite(value):
        raise problem(
            "must be a number or a table {speed_mps = [...], e = [...]} of measured points, "
            f"got {short(value)}"
        )
    return float(value)


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


class CurveTable(Section):
    """A target e(v) as a spec writes it (its schema; `_restitution` checks it): measured
    points, impact speeds in m/s and their e."""

    speed_mps: tuple[Number, ...]
    e: tuple[Number, ...]


Restitution = Annotated[
    float | RestitutionCurve,
    PlainValidator(_restitution, json_schema_input_type=float | CurveTable),
]
"""A target e: a number, or an e(v) curve from a table of measured points."""


class ContactTarget(Section):
    """What a calibrated contact must deliver; None means: as the global contact, or default.

    `restitution`: target e, a number or a table of measured points e(v) (a
    `RestitutionCurve`). `speed_range`: (lowest, highest) normal impact speed in m/s at which
    e is promised (default: from the experiment, see `impactlab.record.contact_pairs`).
    `duration` in s or `max_penetration` in m: the stiffness (both optional, not both);
    `duration_speed`: the impact speed in m/s a curve's `duration` holds at.
    """

    restitution: Restitution | None = None
    speed_range: SpeedRange | None = None
    duration: Annotated[Positive | None, unit("s")] = None
    max_penetration: Annotated[Positive | None, unit("m")] = None
    duration_speed: Annotated[Positive | None, unit("m/s", filled=False)] = None

    @model_validator(mode="after")
    def _one_stiffness(self) -> ContactTarget:
        if self.duration is not None and self.max_penetration is not None:
            raise problem("give duration or max_penetration, not both", "duration")
        if self.duration_speed is not None and self.duration is None:
            raise problem("is the speed a duration holds at: give duration too", "duration_speed")
        return self


class PairContact(ContactTarget):
    """One geom pair's table (`[contact.pairs."ball/plane"]`): any field of `ContactTarget`,
    overriding the global contact's field by field."""

    @model_validator(mode="before")
    @classmethod
    def _not_empty(cls, value: Any) -> Any:
        if isinstance(value, Mapping) and not value:
            raise problem(f"must be a table with some of {', '.join(cls.model_fields)}")
        return value


def _pair_key(key: str) -> str:
    names = key.split("/")
    if len(names) != 2 or not all(names):
        raise problem(f'pair keys are two geom names joined by /, e.g. "ball/plane", got {key!r}')
    if names[0] == names[1]:
        raise problem("a pair needs two geoms")
    return key


PairKey = Annotated[str, AfterValidator(_pair_key)]


def _condim(value: int) -> int:
    if value not in CONDIMS:
        raise problem(f"must be 1, 3, 4 or 6, got {value!r}")
    return value


class Contact(ContactTarget):
    """MuJoCo contact parameters applied to every geom (the handout's `<default><geom>`).

    When `restitution` is set (for every pair, or per pair in `pairs`, keyed by the sorted
    geom names "a/b" once validated), those pairs get calibrated parameters instead
    (`impactlab.contact`): a target e over a range of impact speeds, with an optional contact
    duration or max penetration (the fields of `ContactTarget`). A pair's table overrides
    the global values field by field.
    """

    condim: Annotated[Integer, AfterValidator(_condim)] = 3
    solref: Vector2 = (0.02, 1.0)
    solimp: Vector3or5 = (0.9, 0.95, 0.001, 0.5, 2.0)
    friction: NonNegative3 = (1.0, 0.005, 0.0001)
    allow_coarse_timestep: Flag = False
    pairs: dict[PairKey, PairContact] = Field(default_factory=dict)

    @field_validator("pairs")
    @classmethod
    def _sorted_pairs(cls, pairs: dict[str, PairContact]) -> dict[str, PairContact]:
        out: dict[str, PairContact] = {}
        given: dict[str, str] = {}
        for key, table in pairs.items():
            same = "/".join(sorted(key.split("/")))
            if same in out:
                raise problem(f"names the same pair as {given[same]!r}", key)
            out[same], given[same] = table, key
        return out

    @model_validator(mode="after")
    def _consistent(self) -> Contact:
        if self.solref[0] > 0 and self.solref[1] <= 0:
            raise problem("dampratio must be > 0 when timeconst > 0", "solref")
        s = self.solimp
        if not (0 < s[0] < 1 and 0 < s[1] < 1 and s[2] > 0):
            raise problem(f"need 0 < dmin, dmax < 1 and width > 0, got {list(s)}", "solimp")
        return self


class Plane(Section):
    """The ground plane at z = 0 (absent when `enabled` is false)."""

    enabled: Flag = True
    size: Annotated[NonNegative3, unit("m")] = (5.0, 5.0, 0.1)
    rgba: Rgba = (0.8, 0.8, 0.8, 1.0)


class BodySpec(Section):
    """A free sphere as a spec declares it (`[bodies.NAME]`)."""

    radius: Annotated[Positive, unit("m")]
    mass: Annotated[Positive, unit("kg")]
    pos: Annotated[Vector3, unit("m")]
    vel: Annotated[Vector3, unit("m/s")] = (0.0, 0.0, 0.0)
    angvel: Annotated[Vector3, unit("rad/s")] = (0.0, 0.0, 0.0)
    rgba: Rgba | None = None  # None: a colour of the palette

    @model_validator(mode="after")
    def _massive(self) -> BodySpec:
        inertia = 0.4 * self.mass * self.radius**2  # a solid sphere's, kg m^2
        if min(self.mass, inertia) < MUJOCO_MINVAL:
            raise problem(
                f"with radius {self.radius:g} m its inertia is {inertia:.3g} kg m^2, below "
                f"MuJoCo's minimum {MUJOCO_MINVAL:g} for mass and inertia",
                "mass",
            )
        return self


class Body(BodySpec):
    """A free sphere of a run: its name and its colour resolved."""

    name: str
    rgba: tuple[float, ...]


class Stop(Section):
    """When a run ends.

    `max_time` bounds every run. `bounces`: stop at the apex after the N-th bounce of every
    body on the plane. `at_rest`: stop once every body is slower than `rest_speed` for
    `rest_time`. `separation`: a collision; stop once the bodies have touched and their
    surfaces are this far apart again (a run that ends without that contact is warned about).
    A run is stopped as unstable when its state becomes non-finite, the energy no force
    explains (the budget's residual) rises in one step above its highest so far by more than
    `max_energy_gain` (a fraction of the energy in play so far: the largest kinetic energy,
    potential-energy swing or work of a force), a penetration deepens past `max_penetration`
    (a fraction of the smaller radius) beyond its depth at the start, or MuJoCo raises a
    warning.
    """

    max_time: Annotated[Positive, Field(le=MAX_TIME_S), unit("s")]
    bounces: Annotated[Integer, Field(ge=1)] | None = None
    at_rest: Flag = False
    rest_speed: Annotated[Positive, unit("m/s")] = 1e-3
    rest_time: Annotated[Positive, unit("s")] = 0.05
    separation: Annotated[Positive | None, unit("m")] = None
    max_energy_gain: Positive = 0.1
    max_penetration: Positive = 1.0

    @model_validator(mode="after")
    def _one_ending(self) -> Stop:
        if self.bounces is not None and self.separation is not None:
            raise problem("give either bounces (a drop) or separation (a collision)")
        if self.at_rest and self.rest_time >= self.max_time:
            raise problem(
                f"{self.rest_time} s is not shorter than stop.max_time = {self.max_time} s",
                "rest_time",
            )
        return self


class Logging(Section):
    """What is logged: every N-th step."""

    every: Annotated[Integer, Field(ge=1, le=MAX_LOG_EVERY)] = 1


class SpecDocument(Section):
    """A whole spec (without its `[sweep]`): what one run is made from."""

    name: Name
    description: Annotated[str, Field(strict=True, max_length=10_000)] = ""
    options: Options = Options()
    contact: Contact = Contact()
    plane: Plane = Plane()
    bodies: Annotated[dict[Name, BodySpec], Field(min_length=1, max_length=MAX_BODIES)]
    stop: Stop
    logging: Logging = Logging()

    @model_validator(mode="after")
    def _names_are_free(self) -> SpecDocument:
        for name, why in RESERVED_BODY_NAMES.items():
            if name in self.bodies:
                raise problem(f"{name!r} is {why}: give the body another name", f"bodies.{name}")
        return self

    @model_validator(mode="after")
    def _pairs_name_geoms(self) -> SpecDocument:
        geoms = {*self.bodies, *([PLANE_GEOM] if self.plane.enabled else [])}
        for key in self.contact.pairs:
            unknown = [g for g in key.split("/") if g not in geoms]
            if unknown:
                text = f"no geom named {unknown[0]!r} ({sorted(geoms)})"
                raise problem(text, f"contact.pairs.{key}")
        return self

    @model_validator(mode="after")
    def _stop_fits_the_model(self) -> SpecDocument:
        stop, plane, opt = self.stop, self.plane, self.options
        if stop.bounces is not None and not plane.enabled:
            raise problem("counts bounces on the plane, but plane.enabled is false", "stop.bounces")
        if stop.separation is not None and len(self.bodies) < 2:
            raise problem("a collision needs at least two bodies", "stop.separation")
        if opt.timestep >= stop.max_time:
            raise problem(
                f"{opt.timestep} s is not shorter than stop.max_time = {stop.max_time} s",
                "options.timestep",
            )
        for name, body in self.bodies.items():
            if plane.enabled and body.pos[2] - body.radius < 0:
                raise problem(
                    f"starts below the plane (z - radius = {body.pos[2] - body.radius:g} m)",
                    f"bodies.{name}.pos",
                )
        return self


class MjcfRunOptions(Section):
    """What an MJCF model's run takes from impactlab: how it stops and what it logs (the model
    brings everything else)."""

    stop: Stop
    logging: Logging = Logging()
    keyframe: Annotated[str | None, Field(min_length=1)] = None
    """The model's keyframe the run starts from (`--set keyframe=home`); none: its default pose."""


SECTIONS: Mapping[str, type[Section]] = {
    name: field.annotation
    for name, field in SpecDocument.model_fields.items()
    if isinstance(field.annotation, type) and issubclass(field.annotation, Section)
}
"""The spec's tables of fields, by name (bodies are tables by name of `BodySpec`)."""


def defaults(section: type[Section]) -> dict[str, Any]:
    """A section's default values as a spec document holds them (lists, not tuples);
    required fields, and those not `filled` (see `unit`), are left out."""
    fields = [(k, f) for k, f in section.model_fields.items() if not f.is_required()]
    values = {
        k: f.get_default(call_default_factory=True)
        for k, f in fields
        if not isinstance(f.json_schema_extra, dict) or f.json_schema_extra.get("filled", True)
    }
    return {k: list(v) if isinstance(v, tuple) else v for k, v in values.items()}
