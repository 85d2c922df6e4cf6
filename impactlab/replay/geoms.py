"""The model drawn from the log alone: every visible geom at its size, pose and colour."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np
import rerun as rr

from impactlab.logs.geoms import (
    INFINITE_PLANE_HALF_M,
    PLANE_THICKNESS_M,
    GeomShape,
    ModelScene,
    body_rgba,
    old_plane,
    read_scene,
)
from impactlab.logs.load import RunLog
from impactlab.logs.reader import read_attachments

MARKER_COLOR = (255, 255, 255)
PLANE_MARGIN_M = 0.5


def model_scene(run: RunLog) -> ModelScene:
    """The log's geoms and meshes (the file is read again for its mesh attachments)."""
    needs_meshes = '"mesh": "' in run.scene.get("geoms", "")
    return read_scene(run.scene, read_attachments(run.path) if needs_meshes else {})


def body_path(prefix: str, body: str) -> str:
    """The entity of a body, whose transform follows the body's logged pose."""
    return f"{prefix}/world/bodies/{rr.escape_entity_path_part(body)}"


def rgba255(rgba: Sequence[float]) -> tuple[int, ...]:
    """0-255 colour of an rgba in 0..1."""
    return tuple(round(255 * float(c)) for c in rgba)


def geom_extents(scene: ModelScene) -> dict[str, float]:
    """Per body a geom is drawn on (`world` included, planes left out), the largest distance
    from its frame's origin a point of its geoms reaches, m."""
    out: dict[str, float] = {}
    for g in scene.geoms:
        if g.type == "plane" or not g.visible:
            continue
        if g.mesh is not None and g.mesh in scene.meshes:
            reach = float(np.max(np.linalg.norm(scene.meshes[g.mesh], axis=-1), initial=0.0))
        else:
            reach = float(np.linalg.norm(g.size))
        out[g.body] = max(out.get(g.body, 0.0), float(np.linalg.norm(g.pos)) + reach)
    return out


def log_model(
    rec: rr.RecordingStream,
    run: RunLog,
    scene: ModelScene,
    prefix: str,
    bounds: tuple[np.ndarray, np.ndarray],
) -> None:
    """Every visible geom of the log's table (`old_geoms` for a log written before it), and
    each ball's spin marker; all static."""
    info = run.body_info
    balls = {n: r for n in run.bodies if n in info and (r := info[n].radius)}
    for geom in scene.geoms or old_geoms(run, balls):
        if not geom.visible or (geom.body != "world" and geom.body not in run.bodies):
            continue
        if geom.body == "world":
            path = f"{prefix}/world/static/{rr.escape_entity_path_part(geom.name)}"
        else:
            path = f"{body_path(prefix, geom.body)}/geoms/{rr.escape_entity_path_part(geom.name)}"
        w, x, y, z = geom.quat
        rec.log(
            path,
            rr.Transform3D(translation=geom.pos, quaternion=rr.Quaternion(xyzw=[x, y, z, w])),
            static=True,
        )
        ball = geom.type == "sphere" and geom.body in balls and not any(geom.pos)
        shape = _shape(geom, scene, bounds, wireframe=ball)
        if shape is not None:
            rec.log(path, shape, static=True)
    for name, radius in balls.items():  # a solid dot on the surface and a spoke: the spin
        body = body_path(prefix, name)
        rec.log(
            f"{body}/marker",
            rr.Ellipsoids3D(
                centers=[[0.0, 0.0, radius]],
                half_sizes=[[radius * 0.18] * 3],
                colors=[MARKER_COLOR],
                fill_mode="solid",
            ),
            static=True,
        )
        rec.log(
            f"{body}/spoke",
            rr.LineStrips3D([[[0.0, 0.0, 0.0], [0.0, 0.0, radius]]], colors=[MARKER_COLOR]),
            static=True,
        )


def _shape(
    geom: GeomShape,
    scene: ModelScene,
    bounds: tuple[np.ndarray, np.ndarray],
    *,
    wireframe: bool,
) -> rr.AsComponents | None:
    """The Rerun archetype of one geom in its own frame; None for a type it cannot draw."""
    a, b, c = geom.size
    fill: Literal["densewireframe", "solid"] = "densewireframe" if wireframe else "solid"
    color = rgba255(geom.rgba)
    drawn: dict[str, Any] = {"colors": [color], "labels": [geom.name], "show_labels": False}
    if geom.type == "box":
        return rr.Boxes3D(half_sizes=[[a, b, c]], fill_mode=fill, **drawn)
    if geom.type == "plane":
        reach = np.max(np.abs(np.concatenate([bounds[0][:2], bounds[1][:2]]))) + PLANE_MARGIN_M
        half = [min(s if s > 0 else INFINITE_PLANE_HALF_M, reach) for s in (a, b)]
        thick = PLANE_THICKNESS_M / 2
        return rr.Boxes3D(
            half_sizes=[[*half, thick]], centers=[[0, 0, -thick]], fill_mode="solid", **drawn
        )
    if geom.type in ("sphere", "ellipsoid"):
        radii = [a, a, a] if geom.type == "sphere" else [a, b, c]
        return rr.Ellipsoids3D(half_sizes=[radii], fill_mode=fill, **drawn)
    if geom.type == "capsule":
        return rr.Capsules3D(
            lengths=[2 * b], radii=[a], translations=[[0, 0, -b]], fill_mode=fill, **drawn
        )
    if geom.type == "cylinder":
        return rr.Cylinders3D(lengths=[2 * b], radii=[a], fill_mode=fill, **drawn)
    if geom.mesh is not None and geom.mesh in scene.meshes:  # mesh, hfield
        tri = scene.meshes[geom.mesh]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
        return rr.Mesh3D(
            vertex_positions=tri.reshape(-1, 3),
            vertex_normals=np.repeat(normal, 3, axis=0),
            albedo_factor=color,
        )
    return None


def old_geoms(run: RunLog, balls: Mapping[str, float]) -> list[GeomShape]:
    """The geoms of a log written before the geom table: each ball's sphere in its colour
    (`body_rgba`) and the plane its spec gave it (`old_plane`)."""
    rgba, plane, origin = body_rgba(run), old_plane(run), (0.0, 0.0, 0.0)
    # the colours and the plane's half sizes are tuples of 4 and 2 numbers: pydantic checks
    geoms = [GeomShape(n, n, "sphere", (r, 0, 0), origin, rgba[n]) for n, r in balls.items()]  # type: ignore[arg-type]
    if plane is not None and run.plane_z is not None:
        size, at = (*plane.half_size_m, 0.0), (0.0, 0.0, run.plane_z)
        geoms.append(GeomShape("plane", "world", "plane", size, at, plane.rgba))  # type: ignore[arg-type]
    return geoms
