"""What viewers draw of a run besides its geom table: each body's colour, and the plane of
logs written before the table (`impactlab.scene`).

Logs without the table say these only in their spec: they are read from it here, in the log
format's layer, so no viewer reads a spec.
"""

from __future__ import annotations

from dataclasses import dataclass

from impactlab.logs.geoms import read_scene
from impactlab.logs.load import RunLog
from impactlab.logs.scene import BODY_PALETTE

PLANE_HALF_M = (5.0, 5.0)  # a spec's plane by default
PLANE_RGBA = (0.8, 0.8, 0.8, 1.0)
MAX_SIZE_M = 1e6

Rgba = tuple[float, float, float, float]


@dataclass(frozen=True)
class OldPlane:
    """The plane of a log without a geom table: half sizes in x and y, m; rgba in 0..1."""

    half_size_m: tuple[float, float]
    rgba: Rgba


def body_rgba(run: RunLog) -> dict[str, Rgba]:
    """Each body's colour (rgba in 0..1), in `run.bodies` order.

    A spec's sphere: its geom's colour in the geom table (the geom is named like the body),
    or in a log without the table the colour its spec gave it. Any other body, or one whose
    log does not say: the palette's colour for its place (`scene.BODY_PALETTE`).
    """
    table = {g.name: g.rgba for g in read_scene(run.scene, {}).geoms}
    spec_bodies = run.spec.get("bodies")
    spec_bodies = spec_bodies if isinstance(spec_bodies, dict) else {}
    out = {}
    for i, name in enumerate(run.bodies):
        declared = (spec_bodies.get(name) or {}).get("rgba") if not table else table.get(name)
        palette = BODY_PALETTE[i % len(BODY_PALETTE)]
        out[name] = _numbers(declared, palette, 4, unit=True)
    return out  # type: ignore[return-value]


def old_plane(run: RunLog) -> OldPlane | None:
    """The plane of a log without a geom table, from its spec (5 x 5 m, grey 0.8 by default);
    None when the log has no plane."""
    if run.plane_z is None:
        return None
    plane = run.spec.get("plane") or {}
    sx, sy = _numbers(plane.get("size"), PLANE_HALF_M, 2)
    rgba = _numbers(plane.get("rgba"), PLANE_RGBA, 4, unit=True)
    return OldPlane((sx, sy), rgba)  # type: ignore[arg-type]


def _numbers(
    value: object, default: tuple[float, ...], n: int, *, unit: bool = False
) -> tuple[float, ...]:
    """n numbers of a stored list (each in 0..1 when `unit`, else in (0, 1e6)); else `default`."""
    ok = (
        isinstance(value, list | tuple)
        and len(value) >= n
        and all(
            isinstance(v, int | float)
            and not isinstance(v, bool)
            and ((0.0 <= v <= 1.0) if unit else (0 < v < MAX_SIZE_M))
            for v in value[:n]
        )
    )
    return tuple(float(v) for v in (value if ok else default)[:n])  # type: ignore[index]
