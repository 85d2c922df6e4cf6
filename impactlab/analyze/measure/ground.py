"""The ground of a run as its log describes it: surfaces, each body's clearance, energy references
(docs/analysis.md; older logs with `plane_z` only: its limits)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import polars as pl

from impactlab.logs.load import RunLog, SurfaceInfo
from impactlab.physics import up_vector

CLEARANCE_SCHEMA = pl.Schema(
    {
        "body": pl.String,
        "surface": pl.String,
        "t_ns": pl.Int64,
        "clearance_m": pl.Float64,
    }
)


@dataclass(frozen=True)
class Ground:
    """A run's ground surfaces and its bodies' clearances.

    Attributes:
        surfaces: by name.
        clearance: (body, surface, t_ns, clearance_m) for every logged step.
        up: unit vector against gravity, (3,).
    """

    surfaces: dict[str, SurfaceInfo]
    clearance: pl.DataFrame
    up: np.ndarray

    def reference(self, body: str, first_surface: str | None, rest: float | None) -> str | None:
        """The surface a body's energy is referred to: where it lands first, else the nearest
        one at the first logged step; None when the body cannot be referred to one."""
        if rest is None or not self.surfaces:
            return None
        if first_surface in self.surfaces:
            return first_surface
        mine = [(s, pair) for (b, s), pair in self._by_pair.items() if b == body]
        if mine:  # the nearest surface at the first logged time (one without a value first)
            t0 = min(int(t[0]) for _, (t, _, _) in mine)
            at = [(s, c[0] if ok[0] else None) for s, (t, c, ok) in mine if t[0] == t0]
            unknown = [s for s, c in at if c is None]
            known = [(s, c) for s, c in at if c is not None]
            return unknown[0] if unknown else min(known, key=lambda sc: sc[1])[0]
        return next(iter(self.surfaces)) if len(self.surfaces) == 1 else None

    @cached_property
    def _by_pair(self) -> dict[tuple[str, str], tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per (body, surface): its logged times (sorted), clearances and whether each is set."""
        out: dict[tuple[str, str], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        c = self.clearance
        if not c.height:
            return out
        one = c["body"].n_unique() == 1 and c["surface"].n_unique() == 1  # the common case
        parts = (
            {(c["body"][0], c["surface"][0]): c}
            if one
            else c.partition_by("body", "surface", as_dict=True)
        )
        for (body, surface), frame in parts.items():
            t = frame["t_ns"].to_numpy()
            order = np.argsort(t, kind="stable")
            values = frame["clearance_m"]
            set_ = values.is_not_null().to_numpy()[order]
            out[(str(body), str(surface))] = (t[order], values.to_numpy()[order], set_)
        return out

    def has_clearance(self, body: str, surface: str) -> bool:
        """Whether the log has any clearance row of the body to the surface."""
        return (body, surface) in self._by_pair

    def clearance_at(
        self, body: str, surface: str | None, t_ns: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The body's clearance to the surface at each time (t_ns, int64), and whether the log
        has it there (False: no such pair or time, or a null clearance; the value is then NaN).
        As a left join on (body, surface, t_ns) with one clearance per logged time."""
        values = np.full(len(t_ns), np.nan)
        found = np.zeros(len(t_ns), dtype=bool)
        pair = self._by_pair.get((body, surface)) if surface is not None else None
        if pair is None or not len(t_ns):
            return values, found
        t, c, set_ = pair
        if not t.size:
            return values, found
        spot = np.clip(np.searchsorted(t, t_ns), 0, t.size - 1)
        found = (t[spot] == t_ns) & set_[spot]
        values[found] = c[spot[found]]
        return values, found


def run_ground(run: RunLog) -> Ground:
    """The run's surfaces and clearances (older logs: docs/analysis.md)."""
    up = up_vector(run.gravity)
    surfaces = run.surfaces
    if surfaces is not None:
        clearance = run.clearance.select(list(CLEARANCE_SCHEMA)).cast(CLEARANCE_SCHEMA)
        return Ground({s.name: s for s in surfaces}, clearance, up)
    if run.plane_z is None:
        return Ground({}, pl.DataFrame(schema=CLEARANCE_SCHEMA), up)
    plane = legacy_plane_name(run)
    frames = [
        frame.select(
            pl.lit(name).alias("body"),
            pl.lit(plane).alias("surface"),
            "t_ns",
            (pl.col("z") - run.plane_z - info.radius).alias("clearance_m"),
        )
        for name, info in run.body_info.items()
        if info.radius is not None and (frame := run.bodies.get(name)) is not None
    ]
    clearance = pl.concat(frames) if frames else pl.DataFrame(schema=CLEARANCE_SCHEMA)
    surface = SurfaceInfo(plane, "plane", float(run.plane_z), True)
    return Ground({plane: surface}, clearance.cast(CLEARANCE_SCHEMA), up)


def legacy_plane_name(run: RunLog) -> str:
    """The plane geom's name in an older log: the world's geom in its contact channels."""
    world = run.contacts.filter(pl.col("body1") == "world")["geom1"].unique().sort()
    return str(world[0]) if world.len() else "plane"


@dataclass(frozen=True)
class Reference:
    """Where a body's potential energy is zero: a point (only its height along -gravity
    matters), and the surface its heights are measured from (None: centre above `point`)."""

    point: np.ndarray
    surface: str | None


def references(
    run: RunLog,
    ground: Ground,
    first_surface: dict[str, str],
    start: dict[str, tuple[float, float, float]],
) -> dict[str, Reference]:
    """Per body, its energy reference (docs/analysis.md).

    Args:
        first_surface: per body, the surface of its first ground contact (if any).
        start: per body, its first logged position (the reference without a ground).
    """
    refs = {}
    for name, info in run.body_info.items():
        surface = ground.reference(name, first_surface.get(name), info.rest_height_m)
        if surface is not None and info.rest_height_m is not None:
            level = _level_under(run, ground, name, surface, start.get(name))
            measured = ground.has_clearance(name, surface)
            refs[name] = Reference(
                (level + info.rest_height_m) * ground.up, surface if measured else None
            )
            continue
        refs[name] = Reference(np.asarray(start.get(name, (0.0, 0.0, 0.0)), dtype=float), None)
    return refs


def _level_under(
    run: RunLog,
    ground: Ground,
    body: str,
    surface: str,
    start: tuple[float, float, float] | None,
) -> float:
    """The level (along -gravity, m) of the surface under a body at its first logged step.

    A plane's is its level. Another surface (a table, a mesh, a height field) may reach
    higher elsewhere than under the body (a hand's fingers above its palm): its level under
    the body is at most the body's first height minus its rest height and its first
    clearance (MuJoCo's distance to the surface; not counted when negative, e.g. inside a
    mesh's convex hull), so no body starts below its reference.
    """
    top = ground.surfaces[surface].level_m
    rest = run.body_info[body].rest_height_m
    frame = run.bodies.get(body)
    if ground.surfaces[surface].type == "plane" or start is None or rest is None:
        return top
    if frame is None or not frame.height:
        return top
    under = float(np.dot(start, ground.up)) - rest
    t0 = frame["t_ns"][:1].to_numpy()
    clearance, found = ground.clearance_at(body, surface, t0)
    if found[0] and clearance[0] > 0:
        under -= float(clearance[0])
    return min(top, under)
