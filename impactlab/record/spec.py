"""Experiment specs: TOML files that declare a model, its contact, options, stop rule and logging.

A spec is read in three steps, each checked: the TOML document is merged over the defaults
(`DEFAULTS`), command-line overrides and one sweep point are applied by dotted path, and the
result is validated into a frozen `RunSpec`. Every error names the file, the field and the
problem (`SpecError`).
"""

from __future__ import annotations

import copy
import hashlib
import json
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from impactlab.errors import SpecError
from impactlab.logs.scene import BODY_PALETTE
from impactlab.record.spec_checks import FieldChecks
from impactlab.record.spec_contact import ContactTarget, contact_target, pair_targets

INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")
SPEC_TOP_KEYS = ("name", "description", "options", "contact", "plane", "bodies", "stop", "logging")


DEFAULTS: dict[str, Any] = {
    "description": "",
    "options": {"timestep": 0.002, "integrator": "Euler", "gravity": [0.0, 0.0, -9.81]},
    "contact": {
        "condim": 3,
        "solref": [0.02, 1.0],
        "solimp": [0.9, 0.95, 0.001, 0.5, 2.0],
        "friction": [1.0, 0.005, 0.0001],
        "restitution": None,
        "speed_range": None,
        "duration": None,
        "max_penetration": None,
        "allow_coarse_timestep": False,
        "pairs": {},
    },
    "plane": {"enabled": True, "size": [5.0, 5.0, 0.1], "rgba": [0.8, 0.8, 0.8, 1.0]},
    "stop": {
        "max_time": None,
        "bounces": None,
        "at_rest": False,
        "rest_speed": 1e-3,
        "rest_time": 0.05,
        "separation": None,
        "max_energy_gain": 0.1,
        "max_penetration": 1.0,
    },
    "logging": {"every": 1},
}
BODY_DEFAULTS: dict[str, Any] = {
    "radius": None,
    "mass": None,
    "pos": None,
    "vel": [0.0, 0.0, 0.0],
    "angvel": [0.0, 0.0, 0.0],
    "rgba": None,
}


@dataclass(frozen=True)
class Body:
    """A free sphere: radius in m, mass in kg, initial position (m) and velocities (m/s, rad/s)."""

    name: str
    radius: float
    mass: float
    pos: tuple[float, float, float]
    vel: tuple[float, float, float]
    angvel: tuple[float, float, float]
    rgba: tuple[float, float, float, float]


@dataclass(frozen=True)
class Contact:
    """MuJoCo contact parameters applied to every geom (the handout's `<default><geom>`).

    When `restitution` is set (for every pair, or per pair in `pairs`, keyed by the sorted
    geom names "a/b"), those pairs get calibrated parameters instead (`impactlab.contact`):
    a target e over a range of impact speeds, with an optional contact duration or max
    penetration. A pair's table overrides the global values field by field.
    """

    condim: int
    solref: tuple[float, ...]
    solimp: tuple[float, ...]
    friction: tuple[float, float, float]
    restitution: float | None = None
    speed_range: tuple[float, float] | None = None
    duration: float | None = None
    max_penetration: float | None = None
    allow_coarse_timestep: bool = False
    pairs: Mapping[str, ContactTarget] | None = None


@dataclass(frozen=True)
class Plane:
    """The ground plane at z = 0 (absent when `enabled` is false)."""

    enabled: bool
    size: tuple[float, float, float]
    rgba: tuple[float, float, float, float]


@dataclass(frozen=True)
class Options:
    """Simulation options: timestep in s, integrator name, gravity in m/s^2."""

    timestep: float
    integrator: str
    gravity: tuple[float, float, float]


@dataclass(frozen=True)
class Stop:
    """When a run ends. Times in s, speeds in m/s, distances in m.

    `max_time` bounds every run. `bounces`: stop at the apex after the N-th bounce of every
    body on the plane. `at_rest`: stop once every body is slower than `rest_speed` for
    `rest_time`. `separation`: a collision; stop once the bodies have touched and their
    surfaces are this far apart again (a run that ends without that contact is warned about).
    A run is stopped as unstable when its state becomes non-finite, its mechanical energy
    grows by more than `max_energy_gain` (fraction of its energy scale) or a penetration
    exceeds `max_penetration` (fraction of the smaller radius).
    """

    max_time: float
    bounces: int | None
    at_rest: bool
    rest_speed: float
    rest_time: float
    separation: float | None
    max_energy_gain: float = 0.1
    max_penetration: float = 1.0


@dataclass(frozen=True)
class RunSpec:
    """One fully resolved run: the experiment's spec with overrides and one sweep point applied."""

    experiment: str
    description: str
    source: str
    options: Options
    contact: Contact
    plane: Plane
    bodies: tuple[Body, ...]
    stop: Stop
    log_every: int
    sweep_values: Mapping[str, Any]
    document: Mapping[str, Any]
    sweep_index: int = 0  # this run's place in its sweep grid
    sweep_size: int = 1  # runs in the grid

    @property
    def spec_hash(self) -> str:
        """SHA-256 (hex) of the resolved document: equal hashes mean identical runs."""
        return spec_hash(self.document)


def spec_hash(document: Mapping[str, Any]) -> str:
    """SHA-256 (hex) of a resolved spec document in canonical JSON."""
    canonical = json.dumps(document, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def read_toml(path: Path) -> dict[str, Any]:
    """Read a TOML file, turning I/O and syntax errors into `SpecError`."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SpecError(str(path), "", "file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(str(path), "", f"cannot read: {exc}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(str(path), "", f"invalid TOML: {exc}") from None


def merge_defaults(raw: Mapping[str, Any], source: str) -> dict[str, Any]:
    """The spec document with every omitted value filled from `DEFAULTS`; unknown keys fail."""
    unknown = sorted(set(raw) - set(SPEC_TOP_KEYS) - {"sweep"})
    if unknown:
        raise SpecError(source, unknown[0], f"unknown key (known: {', '.join(SPEC_TOP_KEYS)})")
    doc: dict[str, Any] = {"name": raw.get("name", Path(source).stem)}
    doc["description"] = raw.get("description", DEFAULTS["description"])
    for section in ("options", "contact", "plane", "stop", "logging"):
        given = raw.get(section, {})
        if not isinstance(given, Mapping):
            raise SpecError(source, section, f"must be a table, got {type(given).__name__}")
        _reject_unknown(given, DEFAULTS[section], section, source)
        doc[section] = {**copy.deepcopy(DEFAULTS[section]), **copy.deepcopy(dict(given))}
    bodies = raw.get("bodies")
    if not isinstance(bodies, Mapping) or not bodies:
        raise SpecError(source, "bodies", "at least one body is required ([bodies.NAME] tables)")
    doc["bodies"] = {}
    for name, body in bodies.items():
        field = f"bodies.{name}"
        if not isinstance(body, Mapping):
            raise SpecError(source, field, f"must be a table, got {type(body).__name__}")
        _reject_unknown(body, BODY_DEFAULTS, field, source)
        doc["bodies"][name] = {**copy.deepcopy(BODY_DEFAULTS), **copy.deepcopy(dict(body))}
    return doc


def _reject_unknown(given: Mapping[str, Any], known: Mapping[str, Any], section: str, src: str):
    unknown = sorted(set(given) - set(known))
    if unknown:
        names = ", ".join(known)
        raise SpecError(src, f"{section}.{unknown[0]}", f"unknown key (known: {names})")


def resolve_path(doc: Mapping[str, Any], path: str) -> list[str]:
    """Split a dotted path and resolve the body shorthand (`ball.mass` -> `bodies.ball.mass`)."""
    keys = path.split(".")
    if keys[0] not in doc and keys[0] in doc.get("bodies", {}):
        keys = ["bodies", *keys]
    return keys


def set_path(doc: dict[str, Any], path: str, value: Any, source: str) -> None:
    """Set an existing field of a resolved document by dotted path; unknown fields fail."""
    keys = resolve_path(doc, path)
    node: Any = doc
    for i, key in enumerate(keys):
        if not isinstance(node, dict) or key not in node:
            known = ", ".join(node) if isinstance(node, dict) else "none"
            where = ".".join(keys[: i + 1])
            raise SpecError(source, path, f"unknown field {where!r} (known here: {known})")
        if i == len(keys) - 1:
            node[key] = value
        node = node[key]


def validate(
    doc: Mapping[str, Any],
    *,
    source: str,
    sweep_values: Mapping[str, Any],
    sweep_point: tuple[int, int] = (0, 1),
) -> RunSpec:
    """Check every field of a resolved document and build the `RunSpec`."""
    v = FieldChecks(source)
    opt = doc["options"]
    options = Options(
        timestep=v.number(opt["timestep"], "options.timestep", min_exclusive=0.0),
        integrator=v.choice(opt["integrator"], "options.integrator", INTEGRATORS),
        gravity=v.vector(opt["gravity"], "options.gravity", 3),
    )
    con = doc["contact"]
    condim = v.integer(con["condim"], "contact.condim")
    if condim not in (1, 3, 4, 6):
        raise SpecError(source, "contact.condim", f"must be 1, 3, 4 or 6, got {condim}")
    solref = v.vector(con["solref"], "contact.solref", 2)
    if solref[0] > 0 and solref[1] <= 0:
        raise SpecError(source, "contact.solref", "dampratio must be > 0 when timeconst > 0")
    solimp = v.vector(con["solimp"], "contact.solimp", (3, 5))
    if not (0 < solimp[0] < 1 and 0 < solimp[1] < 1 and solimp[2] > 0):
        raise SpecError(
            source, "contact.solimp", f"need 0 < dmin, dmax < 1 and width > 0, got {list(solimp)}"
        )
    target = contact_target(v, con, "contact")
    contact = Contact(
        condim=condim,
        solref=solref,
        solimp=solimp,
        friction=v.vector(con["friction"], "contact.friction", 3, min_value=0.0),
        restitution=target.restitution,
        speed_range=target.speed_range,
        duration=target.duration,
        max_penetration=target.max_penetration,
        allow_coarse_timestep=v.boolean(
            con["allow_coarse_timestep"], "contact.allow_coarse_timestep"
        ),
        pairs=pair_targets(v, con["pairs"]),
    )
    pl = doc["plane"]
    plane = Plane(
        enabled=v.boolean(pl["enabled"], "plane.enabled"),
        size=v.vector(pl["size"], "plane.size", 3, min_value=0.0),
        rgba=v.vector(pl["rgba"], "plane.rgba", 4, min_value=0.0, max_value=1.0),
    )
    bodies = tuple(
        _body(v, name, body, index) for index, (name, body) in enumerate(doc["bodies"].items())
    )
    stop = stop_section(v, doc["stop"])
    _check_stop(stop, plane, bodies, options, source)
    log_every = v.integer(doc["logging"]["every"], "logging.every", 1)
    return RunSpec(
        experiment=v.name(doc["name"], "name"),
        description=str(doc["description"]),
        source=source,
        options=options,
        contact=contact,
        plane=plane,
        bodies=bodies,
        stop=stop,
        log_every=log_every,
        sweep_values=dict(sweep_values),
        sweep_index=sweep_point[0],
        sweep_size=sweep_point[1],
        document=copy.deepcopy(dict(doc)),
    )


def stop_section(v: FieldChecks, st: Mapping[str, Any]) -> Stop:
    """The `[stop]` table of a resolved document (every key present), checked."""
    return Stop(
        max_time=v.number(st["max_time"], "stop.max_time", min_exclusive=0.0),
        bounces=None if st["bounces"] is None else v.integer(st["bounces"], "stop.bounces", 1),
        at_rest=v.boolean(st["at_rest"], "stop.at_rest"),
        rest_speed=v.number(st["rest_speed"], "stop.rest_speed", min_exclusive=0.0),
        rest_time=v.number(st["rest_time"], "stop.rest_time", min_exclusive=0.0),
        separation=None
        if st["separation"] is None
        else v.number(st["separation"], "stop.separation", min_exclusive=0.0),
        max_energy_gain=v.number(st["max_energy_gain"], "stop.max_energy_gain", min_exclusive=0.0),
        max_penetration=v.number(st["max_penetration"], "stop.max_penetration", min_exclusive=0.0),
    )


def _body(v: FieldChecks, name: str, body: Mapping[str, Any], index: int) -> Body:
    field = f"bodies.{name}"
    rgba = body["rgba"] if body["rgba"] is not None else BODY_PALETTE[index % len(BODY_PALETTE)]
    return Body(
        name=v.name(name, field),
        radius=v.number(body["radius"], f"{field}.radius", min_exclusive=0.0),
        mass=v.number(body["mass"], f"{field}.mass", min_exclusive=0.0),
        pos=v.vector(body["pos"], f"{field}.pos", 3),
        vel=v.vector(body["vel"], f"{field}.vel", 3),
        angvel=v.vector(body["angvel"], f"{field}.angvel", 3),
        rgba=v.vector(rgba, f"{field}.rgba", 4, min_value=0.0, max_value=1.0),
    )


def _check_stop(
    stop: Stop, plane: Plane, bodies: tuple[Body, ...], options: Options, source: str
) -> None:
    """Reject stop rules that contradict the model or each other."""
    if stop.bounces is not None and stop.separation is not None:
        raise SpecError(source, "stop", "give either bounces (a drop) or separation (a collision)")
    if stop.bounces is not None and not plane.enabled:
        raise SpecError(
            source, "stop.bounces", "counts bounces on the plane, but plane.enabled is false"
        )
    if stop.separation is not None and len(bodies) < 2:
        raise SpecError(source, "stop.separation", "a collision needs at least two bodies")
    if stop.at_rest and stop.rest_time >= stop.max_time:
        raise SpecError(
            source,
            "stop.rest_time",
            f"{stop.rest_time} s is not shorter than stop.max_time = {stop.max_time} s",
        )
    if options.timestep >= stop.max_time:
        raise SpecError(
            source,
            "options.timestep",
            f"{options.timestep} s is not shorter than stop.max_time = {stop.max_time} s",
        )
    for body in bodies:
        if plane.enabled and body.pos[2] - body.radius < 0:
            raise SpecError(
                source,
                f"bodies.{body.name}.pos",
                f"starts below the plane (z - radius = {body.pos[2] - body.radius:g} m)",
            )
