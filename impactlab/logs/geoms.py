"""What draws the model from the log alone: the geom table, the meshes as STL, the /scene."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Annotated, Any, NamedTuple

import numpy as np
import pydantic
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from pydantic import Field, ValidationError

from impactlab.logs import format as logformat
from impactlab.logs.metadata import Number, Text, adapter, one_of, valid_if

if TYPE_CHECKING:
    from impactlab.logs.load import RunLog

SCENE_METADATA = logformat.SCENE_METADATA
STL_MEDIA_TYPE = "model/stl"
STL_HEADER = b"impactlab mesh: binary STL, metres, in the geom's frame".ljust(80, b" ")
STL_RECORD = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attribute", "<u2")])
MAX_TRIANGLES = 20_000_000  # a mesh attachment declaring more is refused (1 GB of STL)
PLANE_THICKNESS_M = 0.001
INFINITE_PLANE_HALF_M = 5.0  # drawn for a plane MuJoCo makes infinite (size 0)
BODY_PALETTE = (
    (1.0, 0.2, 0.2, 1.0),
    (0.2, 0.2, 1.0, 1.0),
    (0.2, 0.8, 0.2, 1.0),
    (0.9, 0.7, 0.1, 1.0),
)
"""Default body colours (rgba, 0..1), in body order: specs and viewers use the same."""
Unit = Annotated[Number, Field(ge=0, le=1)]
Rgba = tuple[Unit, Unit, Unit, Unit]
Vector = tuple[Number, Number, Number]


@pydantic.dataclasses.dataclass(frozen=True)
class GeomShape:
    """A geom as viewers draw it (docs/log-format.md): the body it is drawn on (`world`: a
    static geom), MuJoCo's type and size, its pose in that body's logged frame (m; w, x, y,
    z), its colour, visibility group, the attachment of its mesh and its own body."""

    name: Text
    body: Text
    type: Annotated[
        str,
        one_of(
            *["plane", "hfield", "sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh", "sdf"]
        ),
    ]
    size: Vector
    pos: Vector
    rgba: Rgba
    quat: Annotated[tuple[Number, Number, Number, Number], valid_if(any, "is zero")] = (1, 0, 0, 0)
    group: Annotated[int, Field(strict=True)] = 0
    mesh: Text | None = None
    model_body: Text = ""

    @property
    def visible(self) -> bool:
        """Drawn by default: in a group MuJoCo's viewer shows (0-2), and not fully transparent."""
        return self.group in range(3) and self.rgba[3] > 0


@pydantic.dataclasses.dataclass(frozen=True)
class FlexShape:
    """A flex as viewers draw it: its vertices are the logged bodies `bodies`, in order;
    `cells` index them: triangles (a 2D flex, a 3D flex's boundary) or segments (1D)."""

    name: Text
    bodies: tuple[Text, ...]
    cells: tuple[tuple[Annotated[int, Field(strict=True)], ...], ...]
    rgba: Rgba

    @pydantic.model_validator(mode="after")
    def _cells_index_vertices(self) -> FlexShape:
        n = len(self.bodies)
        if not all(2 <= len(c) <= 3 and all(0 <= v < n for v in c) for c in self.cells):
            raise ValueError("a flex's cells do not index its vertices")
        return self


@dataclass
class ModelScene:
    """The geoms of a log, their meshes' triangles (m, 3, 3) by attachment, its flexes, and
    one problem per row of the table that could not be read."""

    geoms: list[GeomShape]
    meshes: dict[str, np.ndarray]
    problems: list[str]
    flexes: list[FlexShape] = field(default_factory=list)


def mesh_attachment(name: str, *, hfield: bool = False) -> str:
    """The attachment name of a mesh (or a height field's triangulation)."""
    return f"{'hfields' if hfield else 'meshes'}/{name}.stl"


def scene_record(
    geoms: Sequence[GeomShape], meshes: Mapping[str, np.ndarray], flexes: Sequence[FlexShape] = ()
) -> dict[str, str]:
    """The `impactlab.scene` metadata record: every value a string."""
    table = adapter(list[GeomShape]).dump_python(list(geoms), mode="json")
    listed = [
        {"name": n.split("/", 1)[-1].removesuffix(".stl"), "attachment": n, "triangles": len(t)}
        for n, t in meshes.items()
    ]
    out = {"geoms": json.dumps(table), "meshes": json.dumps(listed)}
    flex_table = adapter(list[FlexShape]).dump_python(list(flexes), mode="json")
    return out | ({"flexes": json.dumps(flex_table)} if flexes else {})


def encode_stl(triangles: np.ndarray) -> bytes:
    """Binary STL of triangles (m, 3, 3), normals computed (zero for a degenerate one)."""
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    records = np.zeros(len(tri), STL_RECORD)
    records["normal"], records["vertices"] = normal, tri
    return STL_HEADER + np.uint32(len(tri)).tobytes() + records.tobytes()


def decode_stl(data: bytes) -> np.ndarray:
    """Triangles (m, 3, 3) float64 of a binary STL; ValueError when it is not one of the
    declared size, holds too many triangles, or a vertex that is not finite."""
    if len(data) < 84:
        raise ValueError(f"{len(data)} bytes: shorter than an STL header")
    count = int.from_bytes(data[80:84], "little")
    if count > MAX_TRIANGLES or len(data) != 84 + count * STL_RECORD.itemsize:
        raise ValueError(f"{len(data)} bytes do not hold the {count} triangles declared")
    tri = np.frombuffer(data, STL_RECORD, count=count, offset=84)["vertices"].astype(np.float64)
    if not np.all(np.isfinite(tri)):
        raise ValueError("a vertex is not a finite number")
    return tri


def read_scene(record: Mapping[str, str] | None, attachments: Mapping[str, bytes]) -> ModelScene:
    """The geoms and meshes a log describes; a geom that cannot be read is left out, with one
    problem (a log without the record has no geoms and no problem)."""
    scene, record = ModelScene([], {}, []), record or {}
    try:
        table = adapter(list[Any]).validate_json(record.get("geoms", "[]"))
    except ValidationError as exc:
        wrong = "not JSON" if exc.errors()[0]["type"] == "json_invalid" else "not a list"
        scene.problems.append(f"{SCENE_METADATA} geoms: {wrong}")
        return scene
    for i, item in enumerate(table):
        try:
            geom = adapter(GeomShape).validate_python(item)
            if geom.mesh is not None and geom.mesh not in scene.meshes:
                where = f"mesh {geom.mesh!r}: "
                if geom.mesh not in attachments:
                    raise ValueError(where + "attachment missing")
                scene.meshes[geom.mesh] = decode_stl(attachments[geom.mesh])
        except ValueError as exc:  # ValidationError too
            scene.problems.append(f"{SCENE_METADATA} geoms[{i}]: {_said(exc)}")
            continue
        scene.geoms.append(
            replace(geom, quat=tuple(np.array(geom.quat) / np.linalg.norm(geom.quat)))
        )
    try:
        scene.flexes = adapter(list[FlexShape]).validate_json(record.get("flexes", "[]"))
    except ValueError as exc:
        scene.problems.append(f"{SCENE_METADATA} flexes: {_said(exc)}")
    return scene


def _said(exc: ValueError) -> str:
    """A problem in one line: a validation error's first, `<where>: <what>`."""
    if not isinstance(exc, ValidationError):
        return str(exc)
    error = exc.errors()[0]
    where = ".".join(map(str, error["loc"])) or "the row"
    return f"{where}: {error['msg'].removeprefix('Value error, ')}"


def scene_update(
    geoms: Sequence[GeomShape], meshes: Mapping[str, np.ndarray] | None = None
) -> SceneUpdate:
    """One entity per visible geom (id: its name) in the frame it is drawn on: boxes and planes
    as cubes (a plane `PLANE_THICKNESS_M` thick, its top at the plane), spheres, ellipsoids,
    cylinders, capsules (a cylinder and two spheres), meshes and height fields as STL models
    (the bytes of the mesh attachment); a mesh geom without its triangles is left out."""
    update = SceneUpdate()
    stls = {name: encode_stl(triangles) for name, triangles in (meshes or {}).items()}
    for geom in geoms:
        stl = stls.get(geom.mesh) if geom.mesh is not None else None
        if not geom.visible or geom.type == "sdf" or (geom.mesh is not None and stl is None):
            continue
        entity: SceneEntity = update.entities.add()
        entity.frame_id = logformat.WORLD_FRAME if geom.body == "world" else geom.body
        entity.id, entity.frame_locked = geom.name, geom.body != "world"
        meta = entity.metadata.add()
        meta.key, meta.value = "type", geom.type
        _primitives(entity, geom, stl)
    return update


def _primitives(entity: SceneEntity, geom: GeomShape, stl: bytes | None) -> None:
    """The geom's primitives, each posed (shifted along the geom's z axis) and coloured."""
    a, b, c = geom.size
    parts: list[tuple[Any, tuple[float, float, float], float]] = []  # primitive, size, shift
    if geom.type == "plane":
        sx, sy = (s if s > 0 else INFINITE_PLANE_HALF_M for s in (a, b))
        cube = entity.cubes.add()
        parts.append((cube, (2 * sx, 2 * sy, PLANE_THICKNESS_M), -PLANE_THICKNESS_M / 2))
    elif geom.type == "box":
        parts.append((entity.cubes.add(), (2 * a, 2 * b, 2 * c), 0))
    elif geom.type in ("sphere", "ellipsoid"):
        radii = (a, a, a) if geom.type == "sphere" else (a, b, c)
        parts.append((entity.spheres.add(), tuple(2 * r for r in radii), 0))  # type: ignore[arg-type]
    elif geom.type in ("cylinder", "capsule"):
        cylinder = entity.cylinders.add()
        cylinder.bottom_scale = cylinder.top_scale = 1.0
        parts.append((cylinder, (2 * a, 2 * a, 2 * b), 0))
        ends = (-b, b) if geom.type == "capsule" else ()
        parts += [(entity.spheres.add(), (2 * a, 2 * a, 2 * a), end) for end in ends]
    elif stl is not None:  # mesh, hfield
        model = entity.models.add(media_type=STL_MEDIA_TYPE, data=stl, override_color=True)
        model.scale.x = model.scale.y = model.scale.z = 1.0
        parts.append((model, (0, 0, 0), 0))
    w, x, y, z = geom.quat
    z_axis = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    for prim, size, shift in parts:
        if prim.DESCRIPTOR.name != "ModelPrimitive":
            prim.size.x, prim.size.y, prim.size.z = size
        pos = np.asarray(geom.pos) + shift * z_axis
        prim.pose.position.x, prim.pose.position.y, prim.pose.position.z = (float(v) for v in pos)
        o = prim.pose.orientation
        o.w, o.x, o.y, o.z = geom.quat
        prim.color.r, prim.color.g, prim.color.b, prim.color.a = geom.rgba


def body_rgba(run: RunLog) -> dict[str, tuple[float, ...]]:
    """Each body's colour (rgba in 0..1), in `run.bodies` order: a spec's sphere's geom's in
    the geom table (named like the body), in a log without the table the colour its spec gave
    it; any other body, or one whose log does not say, the palette's for its place."""
    table = {g.name: g.rgba for g in read_scene(run.scene, {}).geoms}
    bodies = run.spec.get("bodies")
    bodies = bodies if isinstance(bodies, dict) else {}
    out = {}
    for i, name in enumerate(run.bodies):
        declared = table.get(name) if table else (bodies.get(name) or {}).get("rgba")
        out[name] = _numbers(declared, BODY_PALETTE[i % len(BODY_PALETTE)], 4, unit=True)
    return out


class OldPlane(NamedTuple):
    """The plane of a log without a geom table: half sizes (x, y), m; rgba in 0..1."""

    half_size_m: tuple[float, ...]
    rgba: tuple[float, ...]


def old_plane(run: RunLog) -> OldPlane | None:
    """The plane of a log without a geom table, from its spec (5 x 5 m, grey 0.8 by default);
    None when the log has no plane."""
    if run.plane_z is None:
        return None
    plane = run.spec.get("plane") or {}
    half = _numbers(plane.get("size"), (5.0, 5.0), 2)
    return OldPlane(half, _numbers(plane.get("rgba"), (0.8, 0.8, 0.8, 1.0), 4, unit=True))


def _numbers(
    value: object, default: tuple[float, ...], n: int, *, unit: bool = False
) -> tuple[float, ...]:
    """n numbers of a stored list (each in 0..1 when `unit`, else in (0, 1e6)), or `default`."""
    low, high = (0.0, 1.0) if unit else (0.0, 1e6)
    numbers = isinstance(value, list | tuple) and len(value) >= n
    ok = numbers and all(
        isinstance(v, int | float) and not isinstance(v, bool) and low <= v <= high and (unit or v)
        for v in value[:n]  # type: ignore[index]
    )
    return tuple(float(v) for v in (value if ok else default)[:n])  # type: ignore[index]
