"""Names impactlab gives in a user's model: they never clash with the model's own names."""

from __future__ import annotations

import mujoco

SENSOR_PREFIX = "impactlab:"


def sensor_prefix(spec: mujoco.MjSpec) -> str:
    """`SENSOR_PREFIX`, or ``impactlab2:``, ... : the first that no sensor of the model's
    own starts with (the recorder's sensor names cannot clash with the user's)."""
    own = [s.name for s in spec.sensors if s.name]
    prefix, n = SENSOR_PREFIX, 1
    while any(name.startswith(prefix) for name in own):
        n += 1
        prefix = f"{SENSOR_PREFIX[:-1]}{n}:"
    return prefix


def name_unnamed(spec: mujoco.MjSpec) -> None:
    """Name unnamed bodies ``body<i>``, geoms ``geom<i>`` and tendons ``tendon<i>``, with
    ``_`` added until the name is none of the model's own."""
    kinds = (("body", spec.bodies, 1), ("geom", spec.geoms, 0), ("tendon", spec.tendons, 0))
    for kind, elements, first in kinds:
        taken = {e.name for e in elements if e.name}
        for i, element in enumerate(elements):
            if i >= first and not element.name:
                name = f"{kind}{i}"
                while name in taken:
                    name += "_"
                element.name = name
                taken.add(name)
