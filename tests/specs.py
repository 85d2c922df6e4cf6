"""Experiment specs for the tests, built by factories instead of copied TOML.

`drop(...)` is one ball dropped on the ground, `collision(...)` two balls meeting head on in
zero gravity with no ground, `spec(...)` anything else; each returns a fresh dict with the
spec's defaults overridden by keyword, and `toml(spec)` writes it as the text a spec file
holds (what the `record_spec` fixture and `impactlab record` read). `mjcf_drop(...)` is an
MJCF model of one body dropped on a floor. Lengths in m, speeds in m/s, times in s.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

# MuJoCo's direct-form contact, k = 1e5 1/s^2 and zeta = 0.1 (e = 0.744 for a ball on the ground)
DIRECT = {
    "condim": 1,
    "solref": [-100000.0, -63.245553],
    "solimp": [0.9999, 0.9999, 0.001, 0.5, 2.0],
}
# a soft, strongly damped contact (time constant 0.02 s, damping ratio 1): a ball comes to rest
SOFT = {"condim": 1, "solref": [0.02, 1.0], "solimp": [0.9, 0.95, 0.001]}


def ball(
    z: float = 1.0,
    *,
    x: float = 0.0,
    radius: float = 0.1,
    mass: float = 1.0,
    vel: Sequence[float] | None = None,
    angvel: Sequence[float] | None = None,
) -> dict[str, Any]:
    """A ball body at (x, 0, z), at rest unless `vel` / `angvel` (rad/s) are given."""
    body: dict[str, Any] = {"radius": radius, "mass": mass, "pos": [x, 0.0, z]}
    if vel is not None:
        body["vel"] = list(vel)
    if angvel is not None:
        body["angvel"] = list(angvel)
    return body


def spec(
    name: str = "t",
    bodies: Mapping[str, Mapping[str, Any]] | None = None,
    *,
    timestep: float = 0.001,
    max_time: float = 1.0,
    gravity: Sequence[float] | None = None,
    integrator: str | None = None,
    contact: Mapping[str, Any] | None = None,
    plane: bool = True,
    bounces: int | None = None,
    separation: float | None = None,
    every: int | None = None,
    sweep: Mapping[str, Sequence[Any]] | None = None,
    description: str | None = None,
) -> dict[str, Any]:
    """A spec: `bodies` (default one ball 1 m up), the run options, and only the tables given
    (`contact`, `sweep`, `plane = false`, `logging.every`, the stop's `bounces` and
    `separation`)."""
    out: dict[str, Any] = {"name": name}
    if description is not None:
        out["description"] = description
    options: dict[str, Any] = {"timestep": timestep}
    if integrator is not None:
        options["integrator"] = integrator
    if gravity is not None:
        options["gravity"] = list(gravity)
    out["options"] = options
    if contact is not None:
        out["contact"] = dict(contact)
    if not plane:
        out["plane"] = {"enabled": False}
    out["bodies"] = {k: dict(v) for k, v in (bodies or {"ball": ball()}).items()}
    stop: dict[str, Any] = {"max_time": max_time}
    if bounces is not None:
        stop["bounces"] = bounces
    if separation is not None:
        stop["separation"] = separation
    out["stop"] = stop
    if every is not None:
        out["logging"] = {"every": every}
    if sweep is not None:
        out["sweep"] = {k: list(v) for k, v in sweep.items()}
    return out


def drop(
    name: str = "t",
    *,
    z: float = 1.0,
    radius: float = 0.1,
    mass: float = 1.0,
    vel: Sequence[float] | None = None,
    angvel: Sequence[float] | None = None,
    body: str = "ball",
    **options: Any,
) -> dict[str, Any]:
    """One ball (named `body`) released at height `z` above the ground; `options` go to `spec`."""
    ball_ = ball(z, radius=radius, mass=mass, vel=vel, angvel=angvel)
    return spec(name, {body: ball_}, **options)


def collision(
    name: str = "t",
    *,
    names: tuple[str, str] = ("a", "b"),
    x: float = 0.3,
    z: float = 0.0,
    vel: tuple[float, float] = (2.0, -1.0),
    masses: tuple[float, float] = (1.0, 1.0),
    radius: float = 0.1,
    separation: float = 0.05,
    **options: Any,
) -> dict[str, Any]:
    """Two balls at x = -`x` and +`x` (height `z`) moving along x at `vel`, in zero gravity
    with no ground; the run stops at `separation` after they part. `options` go to `spec`."""
    bodies = {
        n: ball(z, x=sign * x, radius=radius, mass=m, vel=None if v == 0 else [v, 0.0, 0.0])
        for n, sign, v, m in zip(names, (-1.0, 1.0), vel, masses, strict=True)
    }
    options.setdefault("gravity", [0.0, 0.0, 0.0])
    return spec(name, bodies, plane=False, separation=separation, **options)


def mjcf_drop(
    name: str, shape: str, size: str, z: float, *, euler: str = "0 0 0", condim: int = 1
) -> str:
    """An MJCF model: a 1 kg body of one geom (`shape`, `size` as MJCF writes it) at rest at
    height `z`, turned by `euler` (degrees), above a floor, with the DIRECT contact."""
    solref, solimp = (" ".join(f"{v:.10g}" for v in DIRECT[k]) for k in ("solref", "solimp"))
    return f"""<mujoco model="{name}">
  <option timestep="0.0001" gravity="0 0 -9.81"/>
  <default><geom condim="{condim}" solref="{solref}" solimp="{solimp}"/></default>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="{name}" pos="0 0 {z}" euler="{euler}">
      <freejoint/>
      <geom name="{name}" type="{shape}" size="{size}" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""


def toml(spec: Mapping[str, Any]) -> str:
    """The spec as TOML text: top-level values first, then one [table] per dict."""
    lines: list[str] = []
    _table(lines, (), spec)
    return "\n".join(lines).strip() + "\n"


def write(folder: Path, spec: Mapping[str, Any]) -> Path:
    """Write `spec` to `folder/<name>.toml` and return the file's path."""
    path = folder / f"{spec['name']}.toml"
    path.write_text(toml(spec))
    return path


_BARE = re.compile(r"[A-Za-z0-9_-]+")


def _key(key: str) -> str:
    return key if _BARE.fullmatch(key) else json.dumps(key)


def _value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, Sequence):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    raise TypeError(f"no TOML for {value!r}")


def _table(lines: list[str], path: tuple[str, ...], table: Mapping[str, Any]) -> None:
    tables = [(k, v) for k, v in table.items() if isinstance(v, Mapping)]
    if path and (not tables or len(tables) < len(table)):  # no header for [bodies] alone
        lines.append(f"[{'.'.join(_key(k) for k in path)}]")
    lines += [f"{_key(k)} = {_value(v)}" for k, v in table.items() if not isinstance(v, Mapping)]
    for key, sub in tables:
        _table(lines, (*path, key), sub)
