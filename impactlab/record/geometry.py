"""The shapes of a model as the log describes them: its rigid bodies, ground and extents."""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from impactlab import physics
from impactlab.logs.metadata import Surface

SPREAD_DIRECTIONS = 2000
"""Directions spread over the sphere, besides each geom's own axes, for a body's rest height."""
NO_DISTANCE_TYPES = frozenset({int(mujoco.mjtGeom.mjGEOM_HFIELD), int(mujoco.mjtGeom.mjGEOM_SDF)})
"""Geom types MuJoCo's distance sensor does not measure: no clearance to these surfaces."""


def type_name(model: mujoco.MjModel, g: int) -> str:
    """The geom's type as a word: plane, sphere, box, mesh, ..."""
    name: str = mujoco.mjtGeom(int(model.geom_type[g])).name
    return name.removeprefix("mjGEOM_").lower()


def flex_name(model: mujoco.MjModel, f: int) -> str:
    """The flex's name, or ``flex<f>`` when it has none."""
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_FLEX, f) or f"flex{f}"


def can_collide(model: mujoco.MjModel, g1: int, g2: int) -> bool:
    """Whether MuJoCo's contype/conaffinity filter lets the two geoms collide."""
    return bool(
        (model.geom_contype[g1] & model.geom_conaffinity[g2])
        or (model.geom_contype[g2] & model.geom_conaffinity[g1])
    )


def is_static(model: mujoco.MjModel, g: int) -> bool:
    """Whether the geom never moves in a run: its body is welded to the world or to a
    mocap body (placed by the user, not simulated)."""
    root = int(model.body_weldid[model.geom_bodyid[g]])
    return root == 0 or int(model.body_dofnum[root]) == 0


def collides(model: mujoco.MjModel, g: int) -> bool:
    """Whether the geom takes part in collisions at all (contype or conaffinity set)."""
    return bool(model.geom_contype[g] or model.geom_conaffinity[g])


@dataclass(frozen=True)
class RigidBody:
    """A body MuJoCo moves as one: a body with joints and every body welded to it.

    A massless or welded child (a robot's foot, a camera mount) belongs to it, as MuJoCo's
    `body_weldid` says. The frame the log follows is the members' joint centre of mass and
    principal axes of inertia, given in the root body's frame (`pos`, `quat`).
    """

    root: int
    members: tuple[int, ...]
    mass: float
    inertia: tuple[float, float, float]
    pos: tuple[float, float, float]
    quat: tuple[float, float, float, float]


def rigid_bodies(model: mujoco.MjModel, data: mujoco.MjData) -> list[RigidBody]:
    """Every rigid body that moves, in model order (`data`: any pose, kinematics done)."""
    members: dict[int, list[int]] = {}
    for b in range(1, model.nbody):
        root = int(model.body_weldid[b])
        if root != 0 and int(model.body_dofnum[root]) > 0:
            members.setdefault(root, []).append(b)
    out = []
    for root, bodies in members.items():
        mass, xs = model.body_mass[bodies], data.xipos[bodies]
        total = float(mass.sum())
        com = mass @ xs / total if total > 0 else data.xipos[root].copy()
        rot, r = data.ximat[bodies].reshape(-1, 3, 3), xs - com
        tensor = np.einsum("bij,bj,bkj->ik", rot, model.body_inertia[bodies], rot)  # own
        tensor += (mass @ (r * r).sum(axis=1)) * np.eye(3) - np.einsum("b,bi,bj->ij", mass, r, r)
        moments, axes = np.linalg.eigh(tensor)
        if len(bodies) == 1:  # MuJoCo's own principal frame, exactly
            moments, axes = model.body_inertia[root].copy(), data.ximat[root].reshape(3, 3)
        elif np.linalg.det(axes) < 0:
            axes[:, 2] *= -1
        frame = data.xmat[root].reshape(3, 3)
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, (frame.T @ axes).ravel())
        pos = frame.T @ (com - data.xpos[root])
        out.append(
            RigidBody(
                root,
                tuple(bodies),
                total,
                (float(moments[0]), float(moments[1]), float(moments[2])),
                (float(pos[0]), float(pos[1]), float(pos[2])),
                (float(quat[0]), float(quat[1]), float(quat[2]), float(quat[3])),
            )
        )
    return out


def rigid_geoms(model: mujoco.MjModel, body: RigidBody) -> list[int]:
    """The collision geoms of a rigid body's members."""
    own = np.flatnonzero(np.isin(model.geom_bodyid, body.members))
    return [int(g) for g in own if collides(model, int(g))]


def motion(model: mujoco.MjModel, body: RigidBody) -> str:
    """How a rigid body moves: "free" for a lone body on a free joint (it flies on a
    parabola between contacts), "articulated" for a body of a jointed tree."""
    root = body.root
    free = int(model.body_jntnum[root]) == 1 and int(
        model.jnt_type[model.body_jntadr[root]]
    ) == int(mujoco.mjtJoint.mjJNT_FREE)
    tree = {int(b) for b in np.flatnonzero(model.body_rootid == model.body_rootid[root])}
    return "free" if free and tree <= set(body.members) else "articulated"


def gravity(model: mujoco.MjModel) -> np.ndarray:
    """The gravity the model simulates, m/s^2, (3,): zero when its flag disables gravity."""
    if int(model.opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY):
        return np.zeros(3)
    return np.asarray(model.opt.gravity, dtype=float).copy()


def ground_geoms(model: mujoco.MjModel, free_geoms: list[int]) -> list[int]:
    """Static geoms that at least one of `free_geoms` (geoms of rigid bodies) can collide
    with, in model order."""
    return [
        g
        for g in range(model.ngeom)
        if is_static(model, g) and any(can_collide(model, g, f) for f in free_geoms)
    ]


def up_vector(model: mujoco.MjModel) -> np.ndarray:
    """Unit vector against the model's gravity (`physics.up_vector`)."""
    return physics.up_vector(gravity(model))


def support(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    g: int,
    dirs: np.ndarray,
    origin: np.ndarray | None = None,
) -> np.ndarray:
    """Support of geom g along world directions: max over its points p of (p - origin) . d.

    Args:
        dirs: unit directions in the world frame, (k, 3).
        origin: (3,) point the support is measured from (default: the world origin).

    Returns:
        (k,) m. A plane has no finite support: its origin's projection is returned.
    """
    rot = data.geom_xmat[g].reshape(3, 3)
    local = dirs @ rot  # each direction in the geom's frame
    size = model.geom_size[g]
    kind = int(model.geom_type[g])
    x, y, z = np.abs(local[:, 0]), np.abs(local[:, 1]), np.abs(local[:, 2])
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        extent = np.full(len(dirs), size[0])
    elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        extent = size[0] + size[1] * z
    elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
        extent = size[0] * np.hypot(x, y) + size[1] * z
    elif kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
        extent = np.sqrt((size[0] * x) ** 2 + (size[1] * y) ** 2 + (size[2] * z) ** 2)
    elif kind == mujoco.mjtGeom.mjGEOM_BOX:
        extent = size[0] * x + size[1] * y + size[2] * z
    elif kind == mujoco.mjtGeom.mjGEOM_MESH:
        extent = _blocked_max(mesh_hull(model, g)[0], local)  # hull vertices x directions
    elif kind == mujoco.mjtGeom.mjGEOM_HFIELD:
        extent = size[2] * z  # the top of the field's elevation range
    else:  # plane, sdf
        extent = np.zeros(len(dirs))
    centre = data.geom_xpos[g] if origin is None else data.geom_xpos[g] - origin
    reach: np.ndarray = dirs @ centre + extent
    return reach


def mesh_hull(model: mujoco.MjModel, g: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A mesh geom's convex hull as MuJoCo computed it, in the geom's frame: vertices (n, 3),
    outward unit face normals (f, 3) and each face's support along its normal (f,), the
    hull's extent in that direction. A mesh without one (too few vertices for MuJoCo to build
    it) gives its vertices and no faces."""
    mesh = int(model.geom_dataid[g])
    start, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
    vertices = np.asarray(model.mesh_vert[start : start + count], dtype=float)
    adr = int(model.mesh_graphadr[mesh])
    if adr < 0:
        return vertices, np.empty((0, 3)), np.empty(0)
    graph = model.mesh_graph
    numvert, numface = int(graph[adr]), int(graph[adr + 1])
    ids = np.asarray(graph[adr + 2 + numvert : adr + 2 + 2 * numvert], dtype=int)
    at = adr + 2 + 3 * numvert + 3 * numface
    faces = np.asarray(graph[at : at + 3 * numface], dtype=int).reshape(-1, 3)
    v = vertices[faces]
    normals = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    length = np.linalg.norm(normals, axis=1)
    kept = length > 0
    normals = normals[kept] / length[kept, None]
    corner = v[kept, 0]
    centre = vertices[ids].mean(axis=0)
    outward = np.where((np.einsum("ij,ij->i", normals, corner - centre) >= 0)[:, None], 1, -1)
    normals = normals * outward
    return vertices[ids], normals, np.einsum("ij,ij->i", normals, corner)


def spread_directions(n: int = SPREAD_DIRECTIONS) -> np.ndarray:
    """n unit vectors spread evenly over the sphere (Fibonacci lattice), (n, 3)."""
    i = np.arange(n) + 0.5
    polar = np.arccos(1 - 2 * i / n)
    azimuth = np.pi * (1 + 5**0.5) * i
    return np.stack(
        [np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], axis=1
    )


def rest_height(
    model: mujoco.MjModel, data: mujoco.MjData, com: np.ndarray, geoms: list[int]
) -> float:
    """Lowest height of the centre of mass `com` above a flat surface the geoms touch, m.

    `data` must hold the pose `com` is for (mj_kinematics done); see the module docstring.
    """
    dirs = [spread_directions()]
    for g in geoms:
        rot = data.geom_xmat[g].reshape(3, 3)
        dirs += [rot.T, -rot.T]  # the geom's axes in the world frame
    general = np.concatenate(dirs)
    lowest = np.max([support(model, data, g, general, com) for g in geoms], axis=0).min()
    for g in geoms:  # a hull rests on its faces: along a face's normal its support is known
        if int(model.geom_type[g]) != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        _, normals, offsets = mesh_hull(model, g)
        rot = data.geom_xmat[g].reshape(3, 3)
        faces = normals @ rot.T
        own = offsets + faces @ (data.geom_xpos[g] - com)
        others = [support(model, data, h, faces, com) for h in geoms if h != g]
        lowest = min(lowest, np.max([own, *others], axis=0).min(initial=np.inf))
    return float(lowest)


def _blocked_max(points: np.ndarray, dirs: np.ndarray, block: int = 1 << 22) -> np.ndarray:
    """max over points of points @ dirs.T, (k,), in blocks of bounded memory."""
    step = max(1, block // max(1, len(points)))
    return np.concatenate(
        [(points @ dirs[i : i + step].T).max(axis=0) for i in range(0, len(dirs), step)]
    )


def sphere_radius(
    model: mujoco.MjModel, data: mujoco.MjData, com: np.ndarray, geoms: list[int]
) -> float | None:
    """The radius when the body's only collision geom is a sphere centred at its centre of
    mass `com`."""
    if len(geoms) != 1 or int(model.geom_type[geoms[0]]) != mujoco.mjtGeom.mjGEOM_SPHERE:
        return None
    g = geoms[0]
    if not np.allclose(data.geom_xpos[g], com, rtol=0.0, atol=1e-12):
        return None
    return float(model.geom_size[g][0])


def shape_name(model: mujoco.MjModel, geoms: list[int]) -> str:
    """One word for a body's collision shape: its geom's type, or "+"-joined types."""
    if not geoms:
        return "none"
    return "+".join(type_name(model, g) for g in geoms)


def static_potential(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """MuJoCo's potential energy of the bodies that never move (they count in its
    `energy[0]` though they stay put), J."""
    static = [b for b in range(1, model.nbody) if int(model.body_dofnum[model.body_weldid[b]]) == 0]
    g = gravity(model)
    return float(sum(-model.body_mass[b] * g @ data.xipos[b] for b in static))


def surface(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> Surface:
    """A ground geom as the log describes it."""
    up = up_vector(model)
    level = float(support(model, data, g, up[None])[0])
    return Surface(
        name=model.geom(g).name,
        type=type_name(model, g),
        level_m=level,
        distance=int(model.geom_type[g]) not in NO_DISTANCE_TYPES,
    )
