"""The bodies and ground surfaces as a log's run metadata describes them (read side)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class BodyInfo:
    """A moving body as the log's metadata describes it (kg, kg m^2 principal, m).

    `rest_height_m`: the lowest height of its centre of mass above a flat surface it touches
    (older logs: the radius of a sphere, else None); `shape`: its collision geoms' types.
    """

    name: str
    mass: float
    inertia: tuple[float, float, float]
    radius: float | None
    rest_height_m: float | None = None
    shape: str = ""
    geoms: tuple[str, ...] = ()
    motion: str = "free"  # "free": ballistic between contacts, or "articulated"; older: free


@dataclass(frozen=True)
class SurfaceInfo:
    """A ground surface as the log's metadata describes it (see `logs.content.SurfaceMeta`)."""

    name: str
    type: str
    level_m: float
    distance: bool
