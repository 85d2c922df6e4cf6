"""The shapes of a model as the analysis needs them: ground surfaces and each free body's extent.

The analysis never sees MuJoCo, so the recorder describes the geometry once, in the log's
metadata, from the compiled model:

- **Ground surfaces** are the static geoms (welded to the world, not mocap) that a free body's
  geoms can collide with: planes, boxes, meshes, any primitive. Their `level_m` is their
  highest point along -gravity (a plane: the height of its origin).
- **A free body's collision geoms** are the geoms welded to it that collide with anything.
  Its `rest_height_m` is the lowest height its centre of mass can have above a flat surface it
  touches: the minimum over directions d of the support h(d) = max over points p of the body
  of (p - com) . d. For one convex primitive or mesh this is exact (a sphere: its radius, a
  box: its smallest half size); for a body of several geoms it is the minimum over each geom's
  axes, each mesh's face normals and 2,000 directions spread over the sphere.

The body's distance to each surface over time is MuJoCo's own geom distance (a `distance`
sensor per pair of a body geom and a surface, see `impactlab.record.model`).
"""

from __future__ import annotations

import itertools

import mujoco
import numpy as np

from impactlab.logs.content import SurfaceMeta

SPREAD_DIRECTIONS = 2000
"""Directions spread over the sphere, besides each geom's own axes, for a body's rest height."""
NO_DISTANCE_TYPES = frozenset({int(mujoco.mjtGeom.mjGEOM_HFIELD), int(mujoco.mjtGeom.mjGEOM_SDF)})
"""Geom types MuJoCo's distance sensor does not measure: no clearance to these surfaces."""


def type_name(model: mujoco.MjModel, g: int) -> str:
    """The geom's type as a word: plane, sphere, box, mesh, ..."""
    name: str = mujoco.mjtGeom(int(model.geom_type[g])).name
    return name.removeprefix("mjGEOM_").lower()


def can_collide(model: mujoco.MjModel, g1: int, g2: int) -> bool:
    """Whether MuJoCo's contype/conaffinity filter lets the two geoms collide."""
    return bool(
        (model.geom_contype[g1] & model.geom_conaffinity[g2])
        or (model.geom_contype[g2] & model.geom_conaffinity[g1])
    )


def is_static(model: mujoco.MjModel, g: int) -> bool:
    """Whether the geom is welded to the world (and not on a mocap body)."""
    b = int(model.geom_bodyid[g])
    return int(model.body_weldid[b]) == 0


def body_geoms(model: mujoco.MjModel, body: int) -> list[int]:
    """The body's own collision geoms (visual-only geoms excluded; a welded child body's
    geoms are its own, since every moving body is logged)."""
    return [
        g
        for g in range(model.ngeom)
        if int(model.geom_bodyid[g]) == body
        and (model.geom_contype[g] or model.geom_conaffinity[g])
    ]


def moving_bodies(model: mujoco.MjModel) -> list[int]:
    """The bodies that move, in model order: free or jointed, or welded to a body that moves
    (not to the world), not mocap, with mass (a massless body holds no energy)."""
    return [
        b
        for b in range(1, model.nbody)
        if int(model.body_weldid[b]) != 0
        and int(model.body_mocapid[b]) < 0
        and model.body_mass[b] > 0
    ]


def motion(model: mujoco.MjModel, body: int) -> str:
    """How a moving body moves: "free" for a lone rigid body with a free joint (it flies on
    a parabola between contacts), "articulated" for any body of a jointed or welded tree."""
    free = int(model.body_jntnum[body]) == 1 and int(
        model.jnt_type[model.body_jntadr[body]]
    ) == int(mujoco.mjtJoint.mjJNT_FREE)
    alone = int(np.count_nonzero(model.body_rootid == model.body_rootid[body])) == 1
    return "free" if free and alone else "articulated"


def gravity(model: mujoco.MjModel) -> np.ndarray:
    """The gravity the model simulates, m/s^2, (3,): zero when its flag disables gravity."""
    if int(model.opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY):
        return np.zeros(3)
    return np.asarray(model.opt.gravity, dtype=float).copy()


def ground_geoms(model: mujoco.MjModel, free_geoms: list[int]) -> list[int]:
    """Static geoms that at least one of `free_geoms` (geoms of moving bodies) can collide
    with, in model order."""
    return [
        g
        for g in range(model.ngeom)
        if is_static(model, g) and any(can_collide(model, g, f) for f in free_geoms)
    ]


def up_vector(model: mujoco.MjModel) -> np.ndarray:
    """Unit vector against gravity, (3,); +z without gravity."""
    g = gravity(model)
    scale = float(np.abs(g).max())
    if not 0 < scale < np.inf:
        return np.array([0.0, 0.0, 1.0])
    g = g / scale  # a huge gravity (1e300) would overflow the norm to inf
    return -g / np.linalg.norm(g)


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
        extent = (mesh_vertices(model, g) @ local.T).max(axis=0)
    elif kind == mujoco.mjtGeom.mjGEOM_HFIELD:
        extent = size[2] * z  # the top of the field's elevation range
    else:  # plane, sdf
        extent = np.zeros(len(dirs))
    centre = data.geom_xpos[g] if origin is None else data.geom_xpos[g] - origin
    reach: np.ndarray = dirs @ centre + extent
    return reach


def mesh_vertices(model: mujoco.MjModel, g: int) -> np.ndarray:
    """A mesh geom's vertices in the geom's frame, (n, 3)."""
    mesh = int(model.geom_dataid[g])
    start, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
    vertices: np.ndarray = np.asarray(model.mesh_vert[start : start + count], dtype=float)
    return vertices


def mesh_face_normals(model: mujoco.MjModel, g: int) -> np.ndarray:
    """Unit normals of a mesh geom's faces in the geom's frame, (n, 3)."""
    mesh = int(model.geom_dataid[g])
    start, count = int(model.mesh_faceadr[mesh]), int(model.mesh_facenum[mesh])
    faces = np.asarray(model.mesh_face[start : start + count], dtype=int)
    v = mesh_vertices(model, g)
    normals = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])
    length = np.linalg.norm(normals, axis=1)
    unit: np.ndarray = normals[length > 0] / length[length > 0, None]
    return unit


def spread_directions(n: int = SPREAD_DIRECTIONS) -> np.ndarray:
    """n unit vectors spread evenly over the sphere (Fibonacci lattice), (n, 3)."""
    i = np.arange(n) + 0.5
    polar = np.arccos(1 - 2 * i / n)
    azimuth = np.pi * (1 + 5**0.5) * i
    return np.stack(
        [np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar), np.cos(polar)], axis=1
    )


def rest_height(model: mujoco.MjModel, data: mujoco.MjData, body: int, geoms: list[int]) -> float:
    """Lowest centre-of-mass height of the body above a flat surface it touches, m.

    `data` must hold any pose of the body (mj_kinematics done); see the module docstring.
    """
    dirs = [spread_directions()]
    for g in geoms:
        rot = data.geom_xmat[g].reshape(3, 3)
        dirs += [rot.T, -rot.T]  # the geom's axes in the world frame
        if int(model.geom_type[g]) == mujoco.mjtGeom.mjGEOM_MESH:
            normals = mesh_face_normals(model, g) @ rot.T
            dirs += [normals, -normals]
    d = np.concatenate(dirs)
    com = data.xipos[body]
    return float(np.max([support(model, data, g, d, com) for g in geoms], axis=0).min())


def sphere_radius(model: mujoco.MjModel, data: mujoco.MjData, geoms: list[int]) -> float | None:
    """The radius when the body's only collision geom is a sphere at its centre of mass."""
    if len(geoms) != 1 or int(model.geom_type[geoms[0]]) != mujoco.mjtGeom.mjGEOM_SPHERE:
        return None
    g = geoms[0]
    body = int(model.geom_bodyid[g])
    if not np.allclose(data.geom_xpos[g], data.xipos[body], rtol=0.0, atol=1e-12):
        return None
    return float(model.geom_size[g][0])


def shape_name(model: mujoco.MjModel, geoms: list[int]) -> str:
    """One word for a body's collision shape: its geom's type, or "+"-joined types."""
    if not geoms:
        return "none"
    return "+".join(type_name(model, g) for g in geoms)


def static_potential(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """MuJoCo's potential energy of the bodies welded to the world (they count in its
    `energy[0]` though they never move), J."""
    static = [b for b in range(1, model.nbody) if int(model.body_weldid[b]) == 0]
    g = gravity(model)
    return float(sum(-model.body_mass[b] * g @ data.xipos[b] for b in static))


def surface(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> SurfaceMeta:
    """A ground geom as the log describes it."""
    up = up_vector(model)
    level = float(support(model, data, g, up[None])[0])
    return SurfaceMeta(
        name=model.geom(g).name,
        type=type_name(model, g),
        level_m=level,
        distance=int(model.geom_type[g]) not in NO_DISTANCE_TYPES,
    )


def contact_pairs(model: mujoco.MjModel, free: set[int]) -> list[tuple[int, int, int]]:
    """Geom pairs (g1, g2, slots) that may collide and involve a moving body (`free`).

    Pairs within one kinematic tree (a robot's own links) are left out. g1 is the geom of
    the static or lower-numbered tree, so normals point into g2. Sphere-sphere and
    sphere-plane pairs touch at one point; other pairs get four slots.
    """

    def root(g: int) -> int:
        return int(model.body_rootid[model.geom_bodyid[g]])

    def moves(g: int) -> bool:
        return int(model.geom_bodyid[g]) in free

    pairs = []
    for g1, g2 in itertools.combinations(range(model.ngeom), 2):
        b1, b2 = root(g1), root(g2)
        if b1 == b2 or not (moves(g1) or moves(g2)):
            continue
        if not (model.geom_contype[g1] & model.geom_conaffinity[g2]) and not (
            model.geom_contype[g2] & model.geom_conaffinity[g1]
        ):
            continue
        if (moves(g1), b1) > (moves(g2), b2):
            g1, g2 = g2, g1
        simple = {mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_PLANE}
        types = {int(model.geom_type[g1]), int(model.geom_type[g2])}
        pairs.append((g1, g2, 1 if types <= {int(t) for t in simple} else 4))
    return pairs
