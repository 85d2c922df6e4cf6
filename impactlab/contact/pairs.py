"""A user's model as the designer sees it: each pair's radius, gravity and speeds, its `<pair>`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from impactlab.contact.closed_form import ContactModelError
from impactlab.contact.emulation import SCHEMES
from impactlab.contact.params import ContactParams
from impactlab.mjcf.load import load_model

if TYPE_CHECKING:
    import mujoco  # imported where used: `impactlab.contact` loads without it


@dataclass(frozen=True)
class ModelPair:
    """One pair of geoms of a model, as the designer needs it.

    Attributes:
        geom1, geom2: geom names.
        radius_m: the smaller sphere radius in m (None when neither geom is a sphere).
        gravity_mps2: gravity along the contact normal (0 for two moving bodies).
        first_impact_mps: impact speed of a sphere falling from the model's initial state onto
            a static plane, or None when that does not follow from the model.
        condim, friction, margin, gap: the geoms' own contact settings, mixed as MuJoCo mixes
            them (kept in the calibrated ``<pair>``).
        notes: what the user should know about this pair.
    """

    geom1: str
    geom2: str
    radius_m: float | None
    gravity_mps2: float
    first_impact_mps: float | None
    condim: int
    friction: tuple[float, float, float, float, float]
    margin: float
    gap: float
    notes: tuple[str, ...] = ()


def model_integrator(model: mujoco.MjModel) -> str:
    """The integrator of a compiled model, as MJCF names it."""
    import mujoco

    name: str = mujoco.mjtIntegrator(int(model.opt.integrator)).name.removeprefix("mjINT_")
    return {n.upper(): n for n in SCHEMES}.get(name, name)


def model_pairs(model: mujoco.MjModel, names: Sequence[tuple[str, str]]) -> list[ModelPair]:
    """Describe the pairs (geom1, geom2) of a compiled model.

    Raises:
        ContactModelError: a geom name the model does not have, or a geom paired with itself.
    """
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    gravity = np.asarray(model.opt.gravity, float)
    free = {
        int(model.jnt_bodyid[j])
        for j in range(model.njnt)
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE
    }
    out = []
    for g1, g2 in names:
        ids: list[int] = []
        for name in (g1, g2):
            gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
            if gid < 0:
                known = [model.geom(i).name for i in range(model.ngeom) if model.geom(i).name]
                raise ContactModelError(f"no geom named {name!r} (named geoms: {known})")
            ids.append(gid)
        if ids[0] == ids[1]:
            raise ContactModelError(f"a pair needs two geoms, got {g1}/{g2}")
        out.append(_describe(model, data, ids, gravity, free, (g1, g2)))
    return out


def _describe(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    ids: list[int],
    gravity: np.ndarray,
    free: set[int],
    names: tuple[str, str],
) -> ModelPair:
    import mujoco

    sphere, plane = int(mujoco.mjtGeom.mjGEOM_SPHERE), int(mujoco.mjtGeom.mjGEOM_PLANE)
    types = [int(model.geom_type[i]) for i in ids]
    roots = [int(model.body_rootid[model.geom_bodyid[i]]) for i in ids]
    moving = [r in free for r in roots]
    radii = [float(model.geom_size[i][0]) for i, t in zip(ids, types, strict=True) if t == sphere]
    notes: list[str] = []
    first = None
    if all(moving):
        g_normal = 0.0  # two free bodies fall together: no relative gravity
    elif not any(moving):
        raise ContactModelError(f"{names[0]}/{names[1]}: neither geom is on a free body")
    else:
        static = ids[moving.index(False)]
        mover = ids[moving.index(True)]
        if types[moving.index(False)] == plane:
            normal = data.geom_xmat[static].reshape(3, 3)[:, 2]
            g_normal = max(-float(gravity @ normal), 0.0)
            if types[moving.index(True)] == sphere and g_normal > 0.0:
                r = float(model.geom_size[mover][0])
                height = float((data.geom_xpos[mover] - data.geom_xpos[static]) @ normal) - r
                if height > 0.0:
                    first = math.sqrt(2.0 * g_normal * height)
        else:
            g_normal = float(np.linalg.norm(gravity))
            notes.append("the static geom is not a plane: impacts are taken along gravity")
    if not radii:
        notes.append("no sphere in the pair: the contact is designed for one contact point")
    mixed = np.maximum(model.geom_friction[ids[0]], model.geom_friction[ids[1]])
    slide, spin, roll = (float(x) for x in mixed)
    return ModelPair(
        geom1=names[0],
        geom2=names[1],
        radius_m=min(radii) if radii else None,
        gravity_mps2=g_normal,
        first_impact_mps=first,
        condim=int(max(model.geom_condim[ids[0]], model.geom_condim[ids[1]])),
        friction=(slide, slide, spin, roll, roll),
        margin=float(max(model.geom_margin[ids[0]], model.geom_margin[ids[1]])),
        gap=float(max(model.geom_gap[ids[0]], model.geom_gap[ids[1]])),
        notes=tuple(notes),
    )


def pair_element(pair: ModelPair, params: ContactParams) -> str:
    """The ``<pair>`` element: the calibrated solref/solimp and the geoms' own friction."""
    extra = ['friction="' + " ".join(f"{x:g}" for x in pair.friction) + '"']
    if pair.margin or pair.gap:
        extra += [f'margin="{pair.margin!r}"', f'gap="{pair.gap!r}"']
    return params.mjcf_pair(pair.geom1, pair.geom2, condim=pair.condim, extra=extra)


def check_tuned(path: Path, pairs: Sequence[tuple[ModelPair, ContactParams]]) -> None:
    """Compile a tuned model and check MuJoCo has exactly one pair per geom pair, as designed.

    Raises:
        ContactModelError: it does not compile (e.g. an include or asset path relative to
            another folder) or a pair is missing, doubled or different.
    """
    import mujoco

    model = load_model(path)
    for pair, params in pairs:
        g = {
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
            for name in (pair.geom1, pair.geom2)
        }
        found = [
            i
            for i in range(model.npair)
            if {int(model.pair_geom1[i]), int(model.pair_geom2[i])} == g
        ]
        if len(found) != 1:
            raise ContactModelError(
                f"the written model has {len(found)} <pair> elements for "
                f"{pair.geom1}/{pair.geom2} (is there one in an included file?)"
            )
        solref = model.pair_solref[found[0]]
        if not np.allclose(solref, params.solref, rtol=1e-12, atol=0.0):
            raise ContactModelError(
                f"MuJoCo reads solref {list(solref)} for {pair.geom1}/{pair.geom2}, "
                f"expected {list(params.solref)}"
            )
