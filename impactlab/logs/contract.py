"""What the stages read of a run besides its channels: the run record's keys of format 2.

The analysis needs, for each run: which geom pairs were calibrated to a target restitution
and over which normal impact speeds (`contact_targets`), the contact parameters every other
pair shares (`geom_contact`), whether the run brings two bodies together and stops once they
are apart again (`separation_m`), and how far the logged positions of a free flight lag the
parabola of its velocities (`half_step_s`: `physics.half_step_s` of the integrator). The
recorder writes them (`record_values`); readers get them typed as `RunLog` fields. No stage
reads them out of the spec: the spec stays in the log to reproduce the run.

Logs of format 1 lack these keys: `settle` derives them from what those logs say (the spec,
the integrator, the timestep), so readers see the same fields whatever the format. A log
whose spec left a pair's speed range to the experiment does not say it: `speed_range_mps`
is then None.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from impactlab.logs import format as logformat
from impactlab.logs.values import Invalid, json_value, number, quote, real
from impactlab.physics import INTEGRATORS, half_step_s

MAX_SPEED_MPS = 1e6
MAX_HALF_STEP_S = 5.0  # half the longest timestep a log may have (`metadata.MAX_TIMESTEP_S`)
MAX_SEPARATION_M = 1e6
PLANE_GEOM = "plane"  # the plane of a spec's model (format-1 logs name their pairs with it)
SPEC_SOLREF = (0.02, 1.0)  # the spec's contact defaults (format-1 logs: when it omits them)
SPEC_SOLIMP = (0.9, 0.95, 0.001, 0.5, 2.0)


@dataclass(frozen=True)
class PairTarget:
    """A geom pair calibrated to a target restitution (geom names as in the model).

    Attributes:
        restitution: the target e.
        speed_range_mps: (lowest, highest) normal impact speed in m/s at which the contact
            was designed to deliver e; None in a format-1 log that does not say.
    """

    geom1: str
    geom2: str
    restitution: float
    speed_range_mps: tuple[float, float] | None

    @property
    def pair(self) -> str:
        """The pair as specs and tables name it: "geom1/geom2"."""
        return f"{self.geom1}/{self.geom2}"


@dataclass(frozen=True)
class GeomContact:
    """MuJoCo's contact parameters shared by every geom of the model: those of each pair
    without a calibrated contact. solref (2), solimp (3 to 5), as MJCF writes them."""

    solref: tuple[float, ...]
    solimp: tuple[float, ...]


def parse_contact_targets(value: str) -> tuple[PairTarget, ...]:
    """`contact_targets`: JSON [{geom1, geom2, restitution, speed_range_mps: [lo, hi]}]."""
    parsed = json_value(value)
    if not isinstance(parsed, list):
        raise Invalid(f"{quote(value)} is not a JSON list of pairs")
    out = []
    for i, t in enumerate(parsed):
        speeds = t.get("speed_range_mps") if isinstance(t, dict) else None
        ok = (
            isinstance(t, dict)
            and all(isinstance(t.get(k), str) and t[k] for k in ("geom1", "geom2"))
            and real(t.get("restitution"), 0.0, 1.0)
            and isinstance(speeds, list)
            and len(speeds) == 2
            and all(real(v, 0.0, MAX_SPEED_MPS) for v in speeds)
            and 0.0 < speeds[0] <= speeds[1]
        )
        if not ok:
            raise Invalid(f"pair {i} is not {{geom1, geom2, restitution, speed_range_mps}}")
        e, (lo, hi) = float(t["restitution"]), speeds  # type: ignore[misc]
        out.append(PairTarget(t["geom1"], t["geom2"], e, (float(lo), float(hi))))
    return tuple(out)


def parse_geom_contact(value: str) -> GeomContact | None:
    """`geom_contact`: JSON {solref: [2 numbers], solimp: [3 to 5 numbers]}, or empty."""
    if value == "":
        return None  # the geoms do not share one
    parsed = json_value(value)
    solref = parsed.get("solref") if isinstance(parsed, dict) else None
    solimp = parsed.get("solimp") if isinstance(parsed, dict) else None
    ok = (
        isinstance(solref, list)
        and len(solref) == 2
        and isinstance(solimp, list)
        and 3 <= len(solimp) <= 5
        and all(real(v, -math.inf, math.inf) for v in [*solref, *solimp])
    )
    if not ok:
        raise Invalid(f"{quote(value)} is not {{solref: [2 numbers], solimp: [3 to 5]}}")
    return GeomContact(tuple(map(float, solref)), tuple(map(float, solimp)))  # type: ignore[arg-type]


def parse_separation(value: str) -> float | None:
    """`separation_m`: a distance > 0 in m, or empty: the run has no separation rule."""
    if value == "":
        return None
    separation = number(value, 0.0, MAX_SEPARATION_M)
    if separation <= 0.0:
        raise Invalid(f"{quote(value)} is not above 0")
    return separation


def parse_half_step(value: str) -> float:
    """`half_step_s`: a time in [0, MAX_HALF_STEP_S] s."""
    return number(value, 0.0, MAX_HALF_STEP_S)


KEYS = (
    (
        "contact_targets",
        "JSON [{geom1, geom2, restitution, speed_range_mps: [lo, hi]}], m/s",
        parse_contact_targets,
    ),
    (
        "geom_contact",
        "JSON {solref: [2 numbers], solimp: [3 to 5]}, or empty: the geoms differ",
        parse_geom_contact,
    ),
    ("separation_m", "number > 0 m, or empty: no separation rule", parse_separation),
    ("half_step_s", f"number 0 .. {MAX_HALF_STEP_S:g} s: dt / 2, or 0 for RK4", parse_half_step),
)
"""(key, what it holds, parser) of each key, in `format.RUN_KEYS_FORMAT_2`'s order."""


def record_values(
    targets: Sequence[PairTarget],
    geom_contact: GeomContact | None,
    separation_m: float | None,
    half_step: float,
) -> dict[str, str]:
    """The stored strings of the keys, as the recorder writes them."""
    pairs = [
        {
            "geom1": t.geom1,
            "geom2": t.geom2,
            "restitution": float(t.restitution),
            "speed_range_mps": [float(v) for v in t.speed_range_mps or ()],
        }
        for t in targets
    ]
    shared = (
        ""
        if geom_contact is None
        else json.dumps({"solref": list(geom_contact.solref), "solimp": list(geom_contact.solimp)})
    )
    return {
        "contact_targets": json.dumps(pairs),
        "geom_contact": shared,
        "separation_m": "" if separation_m is None else repr(float(separation_m)),
        "half_step_s": repr(float(half_step)),
    }


def optional_keys(version: str | None) -> tuple[str, ...]:
    """The run record's keys a log of this format version may lack."""
    return logformat.RUN_KEYS_ADDED + (logformat.RUN_KEYS_FORMAT_2 if version == "1" else ())


def settle(values: dict[str, Any], problems: dict[str, str]) -> None:
    """Complete the checked values with this module's keys (`metadata.check_metadata`).

    A format-1 log: each key derived from its spec, integrator and timestep. A newer log:
    `half_step_s` must be the integrator's half step, else it is a problem (and unknown).
    """
    dt, integrator = values.get("timestep_s"), values.get("integrator")
    if values.get("log_format_version") == "1":
        spec = values.get("spec", {})
        options = spec.get("options") if isinstance(spec.get("options"), dict) else {}
        if integrator is None and "integrator" not in problems:
            integrator = options.get("integrator", "Euler")
            if integrator in INTEGRATORS:
                values["integrator"] = integrator
        values |= _from_spec(spec)
        if dt is not None and integrator in INTEGRATORS:
            values["half_step_s"] = half_step_s(integrator, dt)
        return
    half = values.get("half_step_s")
    if half is None or dt is None or integrator is None:
        return
    expected = half_step_s(integrator, dt)
    if not math.isclose(half, expected, rel_tol=1e-9, abs_tol=1e-18):
        problems["half_step_s"] = (
            f"{half:g} s, but {integrator} at dt = {dt:g} s gives {expected:g} s"
        )
        del values["half_step_s"]


def _from_spec(spec: Mapping[str, Any]) -> dict[str, Any]:
    """`contact_targets`, `geom_contact` and `separation_m` as a format-1 log's spec gives them
    (its `contact`, `plane`, `bodies` and `stop` tables; a user's model has none but `stop`)."""
    stop = spec.get("stop") or {}
    separation: Any = stop.get("separation")
    out: dict[str, Any] = {
        "separation_m": float(separation) if real(separation, 1e-300, MAX_SEPARATION_M) else None,
        "contact_targets": (),
        "geom_contact": None,
    }
    bodies, contact = spec.get("bodies"), spec.get("contact") or {}
    if not isinstance(bodies, dict):
        return out  # a user's model: its geoms' contact is in model.xml only
    solref, solimp = contact.get("solref", SPEC_SOLREF), contact.get("solimp", SPEC_SOLIMP)
    if all(
        isinstance(v, list | tuple) and n <= len(v) <= m and all(real(x, -1e300, 1e300) for x in v)
        for v, n, m in ((solref, 2, 2), (solimp, 3, 5))
    ):
        out["geom_contact"] = GeomContact(tuple(map(float, solref)), tuple(map(float, solimp)))
    pairs: Any = contact.get("pairs")
    pairs = pairs if isinstance(pairs, dict) else {}
    names = list(bodies)
    candidates = (
        [(PLANE_GEOM, b) for b in names] if (spec.get("plane") or {}).get("enabled", True) else []
    )
    candidates += list(itertools.combinations(names, 2))
    targets = []
    for geom1, geom2 in candidates:  # as the recorder of format 1 paired them
        own = pairs.get("/".join(sorted((geom1, geom2))))
        own = own if isinstance(own, dict) else {}
        e = _pick(own.get("restitution"), contact.get("restitution"))
        if not real(e, 0.0, 1.0):
            continue
        speeds = _pick(own.get("speed_range"), contact.get("speed_range"))
        ok = (
            isinstance(speeds, list)
            and len(speeds) == 2
            and all(real(v, 0.0, MAX_SPEED_MPS) for v in speeds)
        )
        targets.append(
            PairTarget(geom1, geom2, float(e), (float(speeds[0]), float(speeds[1])) if ok else None)
        )
    out["contact_targets"] = tuple(targets)
    return out


def _pick(own: Any, default: Any) -> Any:
    """A pair's own value, else the global one (a spec's pair table overrides field by field)."""
    return own if own is not None else default
