"""Describe every geom of a compiled model for viewers: the log's geom table and meshes."""

from __future__ import annotations

import mujoco
import numpy as np

from impactlab.logs.geoms import FlexShape, GeomShape, mesh_attachment
from impactlab.record.geometry import flex_name, type_name

DEFAULT_RGBA = (0.5, 0.5, 0.5, 1.0)
"""MuJoCo's default geom colour: a geom with a material and this colour shows the material's."""


def describe(
    model: mujoco.MjModel, frames: dict[int, int]
) -> tuple[list[GeomShape], dict[str, np.ndarray]]:
    """Every geom of the model, and the triangles (m, 3, 3) of its meshes and height fields by
    attachment name.

    Each geom is drawn on the rigid body it belongs to (`frames`: the root body's id -> the
    site whose pose the log holds for it), else on the world at its pose at qpos0.
    """
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    shapes: list[GeomShape] = []
    meshes: dict[str, np.ndarray] = {}
    for g in range(model.ngeom):
        root = int(model.body_weldid[model.geom_bodyid[g]])
        site = frames.get(root)
        pos, quat = _relative_pose(data, g, site)
        kind = type_name(model, g)
        data_id, mesh, size = int(model.geom_dataid[g]), None, model.geom_size[g]
        if kind in ("mesh", "sdf") and data_id >= 0:
            mesh = mesh_attachment(model.mesh(data_id).name or f"mesh{data_id}")
            if mesh not in meshes:  # geoms share a mesh: its triangles are built once
                meshes[mesh] = mesh_triangles(model, data_id)
        elif kind == "hfield" and data_id >= 0:
            mesh = mesh_attachment(model.hfield(data_id).name or f"hfield{data_id}", hfield=True)
            if mesh not in meshes:
                meshes[mesh] = hfield_triangles(model, data_id)
            size = model.hfield_size[data_id][:3]
        sx, sy, sz = (float(x) for x in size)
        shapes.append(
            GeomShape(
                name=model.geom(g).name,
                body=model.body(root).name if site is not None else "world",
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


def describe_flexes(model: mujoco.MjModel, logged: dict[int, str]) -> list[FlexShape]:
    """Every flex whose vertices are logged bodies (`logged`: body id -> its name), with the
    triangles (or, for a 1D flex, the segments) that draw it: a 2D flex's elements, a 3D
    flex's boundary (MuJoCo's shell). A flex whose vertices MuJoCo interpolates from other
    dofs is left out (its vertices are no logged bodies)."""
    out = []
    for f in range(model.nflex):
        start, count = int(model.flex_vertadr[f]), int(model.flex_vertnum[f])
        bodies = [int(b) for b in model.flex_vertbodyid[start : start + count]]
        if not all(b in logged for b in bodies):
            continue
        dim = int(model.flex_dim[f])
        if dim == 3:
            adr, num = int(model.flex_shelldataadr[f]), int(model.flex_shellnum[f])
            cells = model.flex_shell[adr : adr + 3 * num].reshape(-1, 3)
        else:
            adr, num = int(model.flex_elemdataadr[f]), int(model.flex_elemnum[f])
            cells = model.flex_elem[adr : adr + (dim + 1) * num].reshape(-1, dim + 1)
        out.append(
            FlexShape(
                name=flex_name(model, f),
                bodies=tuple(logged[b] for b in bodies),
                cells=tuple(tuple(int(v) for v in c) for c in cells),
                rgba=_decimals(model.flex_rgba[f]),
            )
        )
    return out


def _relative_pose(
    data: mujoco.MjData, g: int, site: int | None
) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    """The geom's position and orientation (w, x, y, z) in the frame of `site` (the frame
    whose pose the log holds for the geom's rigid body), or in the world's (None)."""
    rot, origin = np.eye(3), np.zeros(3)
    if site is not None:
        rot, origin = data.site_xmat[site].reshape(3, 3), data.site_xpos[site]
    pos = rot.T @ (data.geom_xpos[g] - origin)
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
    return _decimals(rgba)


def _decimals(rgba: np.ndarray) -> tuple[float, float, float, float]:
    """A float32 colour as floats of their shortest decimals."""
    red, green, blue, alpha = (float(str(x)) for x in rgba)
    return red, green, blue, alpha


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
