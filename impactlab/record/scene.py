"""The static scene for viewers (`foxglove.SceneUpdate`): spheres on their bodies, the plane."""

from __future__ import annotations

from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

from impactlab import logformat
from impactlab.record.model import GeomShape, InstrumentedModel

PLANE_THICKNESS_M = 0.001


def scene_update(inst: InstrumentedModel) -> SceneUpdate:
    """One entity per sphere and plane geom, in its body's frame (world for static geoms)."""
    update = SceneUpdate()
    for geom in inst.geoms:
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
