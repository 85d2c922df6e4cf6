"""The `/scene` a log carries for Foxglove: each geom's primitives posed in the world."""

from __future__ import annotations

import math

import pytest

from impactlab.logs.geoms import (
    INFINITE_PLANE_HALF_M,
    PLANE_THICKNESS_M,
    GeomShape,
    scene_update,
)


def _position(primitive) -> list[float]:
    return [primitive.pose.position.x, primitive.pose.position.y, primitive.pose.position.z]


def test_a_tilted_capsule_has_its_end_spheres_on_its_axis():
    half = math.sqrt(0.5)  # 90 degrees about y: the capsule's axis z along the world's x
    capsule = GeomShape(
        name="c", body="b", type="capsule", size=(0.1, 0.3, 0.0), pos=(1.0, 2.0, 3.0),
        rgba=(1.0, 0.0, 0.0, 1.0), quat=(half, 0.0, half, 0.0),
    )  # fmt: skip
    (entity,) = scene_update([capsule]).entities
    (cylinder,) = entity.cylinders
    assert _position(cylinder) == pytest.approx([1.0, 2.0, 3.0])
    assert sorted(_position(s) for s in entity.spheres) == [
        pytest.approx([0.7, 2.0, 3.0]),
        pytest.approx([1.3, 2.0, 3.0]),
    ]
    assert [cylinder.size.x, cylinder.size.z, entity.spheres[0].size.x] == pytest.approx(
        [0.2, 0.6, 0.2]
    )


def test_a_plane_is_a_thin_box_with_its_top_at_the_plane():
    plane = GeomShape(
        name="p", body="world", type="plane", size=(0.0, 2.0, 1.0), pos=(0.0, 0.0, 0.5),
        rgba=(1.0, 1.0, 1.0, 1.0), quat=(0.0, 1.0, 0.0, 0.0),
    )  # fmt: skip
    (entity,) = scene_update([plane]).entities  # upside down: its top faces -z
    (cube,) = entity.cubes
    assert _position(cube) == pytest.approx([0.0, 0.0, 0.5 + PLANE_THICKNESS_M / 2])
    assert [cube.size.x, cube.size.y, cube.size.z] == pytest.approx(
        [2 * INFINITE_PLANE_HALF_M, 4.0, PLANE_THICKNESS_M]
    )
