"""What draws the model, from the log alone: the geom table and the meshes (no MuJoCo needed).

The recorder describes every geom of the model once (`impactlab.record.geoms`); the log
holds that description in the metadata record `impactlab.scene` and the meshes as
attachments, so a viewer on another machine draws the model without MuJoCo or the model's
files:

- key `geoms`: JSON list, one object per geom in model order:
  `{name, body, model_body, type, size, pos, quat, rgba, group, mesh}`. `body` is the body
  the geom is drawn on: its own body when that body's pose is logged (`/bodies/<body>/state`),
  else its nearest ancestor whose pose is logged, else `world` (a static geom, at its fixed
  world pose). `pos` (m) and `quat` (w, x, y, z) place the geom in the frame whose pose
  `/bodies/<body>/state` logs (the body's centre of mass and principal axes);
  `model_body` is the geom's own body in the model. `type` is MuJoCo's (plane, sphere, capsule,
  ellipsoid, cylinder, box, mesh, hfield, sdf) and `size` MuJoCo's three numbers (half sizes,
  radius and half length, ...; a height field: its x and y half sizes and elevation top).
  `rgba` (0..1) is the geom's colour, its material's when the geom keeps the default colour.
  `group` is MuJoCo's visibility group (its viewer shows groups 0-2). `mesh` names the
  attachment with the geom's triangles (meshes and height fields), else null.
- key `meshes`: JSON list of `{name, attachment, triangles}`.
- attachments `meshes/<mesh name>.stl` (a height field: `hfields/<name>.stl`), media type
  `model/stl`: binary STL, in the geom's frame, m: an 80-byte header, a little-endian uint32
  triangle count, then per triangle 12 float32 (unit normal, three vertices counter-clockwise
  seen from outside) and a uint16 0.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from impactlab.logs import format as logformat

SCENE_METADATA = logformat.SCENE_METADATA
STL_MEDIA_TYPE = "model/stl"
STL_HEADER = b"impactlab mesh: binary STL, metres, in the geom's frame".ljust(80, b" ")
STL_RECORD = np.dtype([("normal", "<f4", (3,)), ("vertices", "<f4", (3, 3)), ("attribute", "<u2")])
GEOM_TYPES = ("plane", "hfield", "sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh", "sdf")
VISIBLE_GROUPS = range(3)
"""The geom groups MuJoCo's viewer shows by default; replays draw those."""
MAX_TRIANGLES = 20_000_000
"""A mesh attachment declaring more triangles is refused (1 GB of STL)."""


@dataclass(frozen=True)
class GeomShape:
    """A geom as viewers draw it (see the module docstring for each field)."""

    name: str
    body: str
    type: str
    size: tuple[float, float, float]
    pos: tuple[float, float, float]
    rgba: tuple[float, float, float, float]
    quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    group: int = 0
    mesh: str | None = None
    model_body: str = ""

    @property
    def visible(self) -> bool:
        """Drawn by default: in a group MuJoCo's viewer shows, and not fully transparent."""
        return self.group in VISIBLE_GROUPS and self.rgba[3] > 0


@dataclass(frozen=True)
class FlexShape:
    """A flex as viewers draw it: its vertices are the logged bodies `bodies` (in vertex
    order); `cells` index them, triangles (a 2D flex, a 3D flex's boundary) or segments (1D)."""

    name: str
    bodies: tuple[str, ...]
    cells: tuple[tuple[int, ...], ...]
    rgba: tuple[float, float, float, float]


@dataclass
class ModelScene:
    """The geoms of a log and their meshes' triangles, (m, 3, 3) float m, by attachment name,
    and its flexes."""

    geoms: list[GeomShape]
    meshes: dict[str, np.ndarray]
    problems: list[str]
    flexes: list[FlexShape] = field(default_factory=list)


def mesh_attachment(name: str, *, hfield: bool = False) -> str:
    """The attachment name of a mesh (or a height field's triangulation)."""
    return f"{'hfields' if hfield else 'meshes'}/{name}.stl"


def scene_record(
    geoms: Sequence[GeomShape],
    meshes: Mapping[str, np.ndarray],
    flexes: Sequence[FlexShape] = (),
) -> dict[str, str]:
    """The `impactlab.scene` metadata record: every value a string."""
    table = [
        {
            "name": g.name,
            "body": g.body,
            "model_body": g.model_body,
            "type": g.type,
            "size": [float(x) for x in g.size],
            "pos": [float(x) for x in g.pos],
            "quat": [float(x) for x in g.quat],
            "rgba": [float(x) for x in g.rgba],
            "group": int(g.group),
            "mesh": g.mesh,
        }
        for g in geoms
    ]
    listed = [
        {"name": _mesh_name(name), "attachment": name, "triangles": len(t)}
        for name, t in meshes.items()
    ]
    flex_table = [
        {
            "name": f.name,
            "bodies": list(f.bodies),
            "cells": [list(c) for c in f.cells],
            "rgba": list(f.rgba),
        }
        for f in flexes
    ]
    return {
        "geoms": json.dumps(table),
        "meshes": json.dumps(listed),
        **({"flexes": json.dumps(flex_table)} if flexes else {}),
    }


def _mesh_name(attachment: str) -> str:
    return attachment.split("/", 1)[-1].removesuffix(".stl")


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
    """Triangles (m, 3, 3) float64 of a binary STL.

    Raises:
        ValueError: not a binary STL of the declared size, too many triangles, or a vertex
            that is not finite.
    """
    if len(data) < 84:
        raise ValueError(f"{len(data)} bytes: shorter than an STL header")
    count = int.from_bytes(data[80:84], "little")
    if count > MAX_TRIANGLES or len(data) != 84 + count * STL_RECORD.itemsize:
        raise ValueError(f"{len(data)} bytes do not hold the {count} triangles declared")
    records = np.frombuffer(data, STL_RECORD, count=count, offset=84)
    tri = records["vertices"].astype(np.float64)
    if not np.all(np.isfinite(tri)):
        raise ValueError("a vertex is not a finite number")
    return tri


def read_scene(record: Mapping[str, str] | None, attachments: Mapping[str, bytes]) -> ModelScene:
    """The geoms and meshes a log describes; geoms that cannot be read are left out, each
    with one problem (a log without the record has no geoms and no problem)."""
    scene = ModelScene([], {}, [])
    if not record:
        return scene
    try:
        table = json.loads(record.get("geoms", "[]"))
    except ValueError:
        scene.problems.append(f"{SCENE_METADATA} geoms: not JSON")
        return scene
    if not isinstance(table, list):
        scene.problems.append(f"{SCENE_METADATA} geoms: not a list")
        return scene
    for i, item in enumerate(table):
        try:
            geom = _geom(item)
        except (TypeError, ValueError, KeyError) as exc:
            scene.problems.append(f"{SCENE_METADATA} geoms[{i}]: {exc}")
            continue
        if geom.mesh is not None and geom.mesh not in scene.meshes:
            data = attachments.get(geom.mesh)
            try:
                if data is None:
                    raise ValueError("attachment missing")
                scene.meshes[geom.mesh] = decode_stl(data)
            except ValueError as exc:
                scene.problems.append(f"{SCENE_METADATA} geoms[{i}] mesh {geom.mesh!r}: {exc}")
                continue
        scene.geoms.append(geom)
    try:
        flexes = json.loads(record.get("flexes", "[]"))
        scene.flexes = [_flex(item) for item in flexes]
    except (TypeError, ValueError, KeyError) as exc:
        scene.problems.append(f"{SCENE_METADATA} flexes: {exc}")
    return scene


def _flex(item: Mapping[str, object]) -> FlexShape:
    """One flex of the table, checked: names, cells that index its vertices, a colour."""
    bodies, cells, rgba = item["bodies"], item["cells"], item["rgba"]
    name = item["name"]
    if not isinstance(name, str) or not isinstance(bodies, list):
        raise TypeError("a flex's name or bodies are not text")
    if not all(isinstance(b, str) for b in bodies) or not isinstance(cells, list):
        raise TypeError("a flex's bodies or cells are malformed")
    n = len(bodies)
    ok = all(
        isinstance(c, list)
        and 2 <= len(c) <= 3
        and all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v < n for v in c)
        for c in cells
    )
    if not ok or not isinstance(rgba, list) or len(rgba) != 4:
        raise ValueError("a flex's cells do not index its vertices, or its rgba is not 4")
    colour = tuple(float(c) for c in rgba if isinstance(c, int | float))
    if len(colour) != 4 or not all(0.0 <= c <= 1.0 for c in colour):
        raise ValueError("a flex's rgba is not within 0..1")
    return FlexShape(name, tuple(bodies), tuple(tuple(c) for c in cells), colour)


def _geom(item: object) -> GeomShape:
    """One row of the table, checked: texts, finite numbers of the right count, a known type."""
    if not isinstance(item, dict):
        raise TypeError("not an object")

    def text(key: str, default: str | None = None) -> str:
        value = item.get(key, default)
        if not isinstance(value, str):
            raise TypeError(f"{key} is not text")
        return value

    def numbers(key: str, n: int, default: Sequence[float] | None = None) -> tuple[float, ...]:
        value = item.get(key, default)
        if (
            not isinstance(value, list | tuple)
            or len(value) != n
            or not all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                for v in value
            )
        ):
            raise ValueError(f"{key} is not {n} finite numbers")
        return tuple(float(v) for v in value)

    kind = text("type")
    if kind not in GEOM_TYPES:
        raise ValueError(f"unknown type {kind!r}")
    mesh = item.get("mesh")
    if mesh is not None and not isinstance(mesh, str):
        raise TypeError("mesh is not text")
    group = item.get("group", 0)
    if not isinstance(group, int) or isinstance(group, bool):
        raise TypeError("group is not a whole number")
    quat = np.array(numbers("quat", 4, (1.0, 0.0, 0.0, 0.0)))
    norm = float(np.linalg.norm(quat))
    if not norm > 0:
        raise ValueError("quat is zero")
    rgba = numbers("rgba", 4)
    if not all(0.0 <= c <= 1.0 for c in rgba):
        raise ValueError("rgba is not within 0..1")
    return GeomShape(
        name=text("name"),
        body=text("body"),
        type=kind,
        size=numbers("size", 3),  # type: ignore[arg-type]
        pos=numbers("pos", 3),  # type: ignore[arg-type]
        rgba=rgba,  # type: ignore[arg-type]
        quat=tuple(float(q) for q in quat / norm),  # type: ignore[arg-type]
        group=group,
        mesh=mesh,
        model_body=text("model_body", ""),
    )
