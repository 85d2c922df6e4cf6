"""The static scene for viewers (`foxglove.SceneUpdate`): spheres on their bodies, the plane."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

from impactlab.logs import format as logformat

PLANE_THICKNESS_M = 0.001

BODY_PALETTE: tuple[tuple[float, float, float, float], ...] = (
    (1.0, 0.2, 0.2, 1.0),
    (0.2, 0.2, 1.0, 1.0),
    (0.2, 0.8, 0.2, 1.0),
    (0.9, 0.7, 0.1, 1.0),
)
"""Default body colours (rgba, 0..1), in body order: specs and viewers use the same."""


@dataclass(frozen=True)
class GeomShape:
    """A geom's shape for viewers: type name, size (MuJoCo's), body name, position and rgba."""

    name: str
    body: str
    type: str
    size: tuple[float, float, float]
    pos: tuple[float, float, float]
    rgba: tuple[float, float, float, float]


def scene_update(geoms: Sequence[GeomShape]) -> SceneUpdate:
    """One entity per sphere and plane geom, in its body's frame (world for static geoms)."""
    update = SceneUpdate()
    for geom in geoms:
        if geom.type not in ("sphere", "plane"):
            continue
        entity: SceneEntity = update.entities.add()
        static = geom.body == "world"
        entity.frame_id = logformat.WORLD_FRAME if static else geom.body
        entity.id = geom.name
        entity.frame_locked = not static
        _add_primitive(entity, geom)
    return update


def _add_primitive(entity: SceneEntity, geom: GeomShape) -> None:
    if geom.type == "sphere":
        prim = entity.spheres.add()
        prim.size.x = prim.size.y = prim.size.z = 2 * geom.size[0]
    else:
        prim = entity.cubes.add()
        prim.size.x, prim.size.y = 2 * geom.size[0], 2 * geom.size[1]
        prim.size.z = PLANE_THICKNESS_M
    prim.pose.position.x, prim.pose.position.y, prim.pose.position.z = geom.pos
    if geom.type == "plane":
        prim.pose.position.z -= PLANE_THICKNESS_M / 2
    prim.pose.orientation.w = 1.0
    prim.color.r, prim.color.g, prim.color.b, prim.color.a = geom.rgba
