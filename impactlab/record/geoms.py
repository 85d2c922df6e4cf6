"""Describe every geom of a compiled model for viewers: the log's geom table and meshes.

See `impactlab.logs.geoms` for what the log holds. Each geom is placed on the body it is
drawn on: its own body when that body's pose is logged, else the nearest ancestor whose pose
is logged, else the world (static geoms, and bodies welded to the world, at their fixed world
pose). Its pose is relative to the frame whose pose the log holds for that body (its
inertial frame: centre of mass and principal axes) and is taken from MuJoCo's kinematics at
the model's reference configuration (qpos0): exact for geoms welded to the body they are
drawn on.
"""

from __future__ import annotations

from collections.abc import Iterable

import mujoco
import numpy as np

from impactlab.logs.geoms import GeomShape, mesh_attachment

DEFAULT_RGBA = (0.5, 0.5, 0.5, 1.0)
"""MuJoCo's default geom colour: a geom with a material and this colour shows the material's."""


def describe(
    model: mujoco.MjModel, logged: Iterable[int]
) -> tuple[list[GeomShape], dict[str, np.ndarray]]:
    """Every geom of the model, and the triangles (m, 3, 3) of its meshes and height fields by
    attachment name.

    Args:
        logged: ids of the bodies whose pose the log holds.
    """
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    with_pose = set(logged)
    shapes: list[GeomShape] = []
    meshes: dict[str, np.ndarray] = {}
    for g in range(model.ngeom):
        frame = _drawn_on(model, int(model.geom_bodyid[g]), with_pose)
        pos, quat = _relative_pose(data, g, frame)
        kind = mujoco.mjtGeom(int(model.geom_type[g])).name.removeprefix("mjGEOM_").lower()
        mesh = None
        if kind == "mesh" and model.geom_dataid[g] >= 0:
            m = int(model.geom_dataid[g])
            mesh = mesh_attachment(model.mesh(m).name or f"mesh{m}")
            meshes.setdefault(mesh, mesh_triangles(model, m))
        elif kind == "hfield" and model.geom_dataid[g] >= 0:
            h = int(model.geom_dataid[g])
            mesh = mesh_attachment(model.hfield(h).name or f"hfield{h}", hfield=True)
            meshes.setdefault(mesh, hfield_triangles(model, h))
        size = model.geom_size[g]
        if kind == "hfield" and model.geom_dataid[g] >= 0:
            size = model.hfield_size[int(model.geom_dataid[g])][:3]
        sx, sy, sz = (float(x) for x in size)
        shapes.append(
            GeomShape(
                name=model.geom(g).name,
                body=model.body(frame).name if frame else "world",
                type=kind,
                size=(sx, sy, sz),
                pos=pos,
                rgba=geom_rgba(model, g),
                quat=quat,
                group=int(model.geom_group[g]),
                mesh=mesh,
                model_body=model.body(int(model.geom_bodyid[g])).name or "world",
            )
        )
    return shapes, meshes


def _drawn_on(model: mujoco.MjModel, body: int, with_pose: set[int]) -> int:
    """The body a geom of `body` is drawn on: itself or its nearest ancestor with a logged
    pose; 0 (the world) when none has one or the body is welded to the world."""
    if int(model.body_weldid[body]) == 0:
        return 0
    b = body
    while b != 0 and b not in with_pose:
        b = int(model.body_parentid[b])
    return b


def _relative_pose(
    data: mujoco.MjData, g: int, frame: int
) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    """The geom's position and orientation (w, x, y, z) in the frame the log gives the pose
    of for body `frame`: its inertial frame (centre of mass, principal axes), which the
    recorder's `FRAMEPOS`/`FRAMEQUAT` sensors on the body measure."""
    rot = data.ximat[frame].reshape(3, 3)
    pos = rot.T @ (data.geom_xpos[g] - data.xipos[frame])
    mat = rot.T @ data.geom_xmat[g].reshape(3, 3)
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, mat.reshape(-1))
    x, y, z = (float(v) for v in pos)
    qw, qx, qy, qz = (float(v) for v in quat)
    return (x, y, z), (qw, qx, qy, qz)


def geom_rgba(model: mujoco.MjModel, g: int) -> tuple[float, float, float, float]:
    """The geom's colour: its rgba, or its material's when it keeps the default colour."""
    rgba = model.geom_rgba[g]
    mat = int(model.geom_matid[g])
    if mat >= 0 and np.allclose(_decimals(rgba), DEFAULT_RGBA):
        rgba = model.mat_rgba[mat]
    red, green, blue, alpha = _decimals(rgba)
    return red, green, blue, alpha


def _decimals(values: np.ndarray) -> tuple[float, ...]:
    """float32 values as floats of their shortest decimals."""
    return tuple(float(str(x)) for x in values)


def mesh_triangles(model: mujoco.MjModel, m: int) -> np.ndarray:
    """A mesh's triangles in its geoms' frame, (nface, 3, 3) m."""
    start, count = int(model.mesh_vertadr[m]), int(model.mesh_vertnum[m])
    vert = np.asarray(model.mesh_vert[start : start + count], dtype=float)
    start, nface = int(model.mesh_faceadr[m]), int(model.mesh_facenum[m])
    faces = np.asarray(model.mesh_face[start : start + nface], dtype=int)
    triangles: np.ndarray = vert[faces]
    return triangles


def hfield_triangles(model: mujoco.MjModel, h: int) -> np.ndarray:
    """A height field's surface as triangles in its geom's frame, (2 (nrow-1)(ncol-1), 3, 3) m.

    MuJoCo's layout: `nrow` rows along y, `ncol` columns along x, elevations 0..1 scaled by
    the top size, spanning [-x, x] by [-y, y].
    """
    nrow, ncol = int(model.hfield_nrow[h]), int(model.hfield_ncol[h])
    sx, sy, top, _ = (float(v) for v in model.hfield_size[h])
    adr = int(model.hfield_adr[h])
    z = np.asarray(model.hfield_data[adr : adr + nrow * ncol], dtype=float).reshape(nrow, ncol)
    x = np.linspace(-sx, sx, ncol)
    y = np.linspace(-sy, sy, nrow)
    grid = np.stack(np.broadcast_arrays(x[None, :], y[:, None], z * top), axis=-1)
    a, b = grid[:-1, :-1], grid[:-1, 1:]
    c, d = grid[1:, :-1], grid[1:, 1:]
    first = np.stack([a, b, d], axis=-2).reshape(-1, 3, 3)
    second = np.stack([a, d, c], axis=-2).reshape(-1, 3, 3)
    return np.concatenate([first, second])
