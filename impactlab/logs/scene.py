"""The static scene for viewers (`foxglove.SceneUpdate`): every visible geom on its body.

One entity per geom (id: the geom's name), in the frame of the body it is drawn on (`world`
for static geoms; the body frames move with `/tf`): boxes and planes as cubes (a plane
`PLANE_THICKNESS_M` thick, its top at the plane), spheres and ellipsoids as spheres,
cylinders as cylinders, capsules as a cylinder and two spheres, meshes and height fields as
binary STL models (`ModelPrimitive`, the same bytes as the log's mesh attachment).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

from impactlab.logs import format as logformat
from impactlab.logs.geoms import STL_MEDIA_TYPE, GeomShape, encode_stl

if TYPE_CHECKING:
    from foxglove_schemas_protobuf.CubePrimitive_pb2 import CubePrimitive
    from foxglove_schemas_protobuf.CylinderPrimitive_pb2 import CylinderPrimitive
    from foxglove_schemas_protobuf.ModelPrimitive_pb2 import ModelPrimitive
    from foxglove_schemas_protobuf.SpherePrimitive_pb2 import SpherePrimitive

    Primitive = CubePrimitive | CylinderPrimitive | ModelPrimitive | SpherePrimitive

__all__ = ["BODY_PALETTE", "PLANE_THICKNESS_M", "GeomShape", "scene_update"]

PLANE_THICKNESS_M = 0.001
INFINITE_PLANE_HALF_M = 5.0
"""Half size drawn for a plane MuJoCo makes infinite (size 0)."""

BODY_PALETTE: tuple[tuple[float, float, float, float], ...] = (
    (1.0, 0.2, 0.2, 1.0),
    (0.2, 0.2, 1.0, 1.0),
    (0.2, 0.8, 0.2, 1.0),
    (0.9, 0.7, 0.1, 1.0),
)
"""Default body colours (rgba, 0..1), in body order: specs and viewers use the same."""


def scene_update(
    geoms: Sequence[GeomShape], meshes: Mapping[str, np.ndarray] | None = None
) -> SceneUpdate:
    """One entity per visible geom (`GeomShape.visible`), in the frame it is drawn on.

    `meshes`: triangles (m, 3, 3) by attachment name; a mesh geom without them is left out.
    """
    update = SceneUpdate()
    stl: dict[str, bytes] = {}
    for geom in geoms:
        if not geom.visible or geom.type == "sdf":
            continue
        if geom.mesh is not None and geom.mesh not in stl:
            if meshes is None or geom.mesh not in meshes:
                continue
            stl[geom.mesh] = encode_stl(meshes[geom.mesh])
        entity: SceneEntity = update.entities.add()
        static = geom.body == "world"
        entity.frame_id = logformat.WORLD_FRAME if static else geom.body
        entity.id = geom.name
        entity.frame_locked = not static
        meta = entity.metadata.add()
        meta.key, meta.value = "type", geom.type
        _add_primitives(entity, geom, stl.get(geom.mesh or ""))
    return update


def _pose(
    prim: Primitive, geom: GeomShape, offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
) -> None:
    """Place a primitive at the geom's pose, shifted by `offset` in the geom's frame."""
    w, x, y, z = geom.quat
    rot = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    pos = np.asarray(geom.pos) + rot @ np.asarray(offset)
    prim.pose.position.x, prim.pose.position.y, prim.pose.position.z = (float(v) for v in pos)
    o = prim.pose.orientation
    o.w, o.x, o.y, o.z = geom.quat


def _color(prim: Primitive, geom: GeomShape) -> None:
    prim.color.r, prim.color.g, prim.color.b, prim.color.a = geom.rgba


def _add_primitives(entity: SceneEntity, geom: GeomShape, stl: bytes | None) -> None:
    a, b, c = geom.size
    if geom.type in ("box", "plane"):
        prim = entity.cubes.add()
        if geom.type == "plane":
            sx, sy = (s if s > 0 else INFINITE_PLANE_HALF_M for s in (a, b))
            prim.size.x, prim.size.y, prim.size.z = 2 * sx, 2 * sy, PLANE_THICKNESS_M
            _pose(prim, geom, (0.0, 0.0, -PLANE_THICKNESS_M / 2))
        else:
            prim.size.x, prim.size.y, prim.size.z = 2 * a, 2 * b, 2 * c
            _pose(prim, geom)
        _color(prim, geom)
    elif geom.type in ("sphere", "ellipsoid"):
        prim = entity.spheres.add()
        radii = (a, a, a) if geom.type == "sphere" else (a, b, c)
        prim.size.x, prim.size.y, prim.size.z = (2 * r for r in radii)
        _pose(prim, geom)
        _color(prim, geom)
    elif geom.type in ("cylinder", "capsule"):
        prim = entity.cylinders.add()
        prim.size.x = prim.size.y = 2 * a
        prim.size.z = 2 * b
        prim.bottom_scale = prim.top_scale = 1.0
        _pose(prim, geom)
        _color(prim, geom)
        if geom.type == "capsule":
            for end in (-b, b):
                cap = entity.spheres.add()
                cap.size.x = cap.size.y = cap.size.z = 2 * a
                _pose(cap, geom, (0.0, 0.0, end))
                _color(cap, geom)
    elif stl is not None:  # mesh, hfield
        prim = entity.models.add()
        prim.scale.x = prim.scale.y = prim.scale.z = 1.0
        prim.media_type = STL_MEDIA_TYPE
        prim.data = stl
        prim.override_color = True
        _pose(prim, geom)
        _color(prim, geom)
