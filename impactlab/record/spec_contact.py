"""The calibrated-contact fields of a spec: a target e over a speed range, globally and per pair.

`[contact]` may ask for `restitution`, `speed_range = [v_lo, v_hi]` (m/s), `duration` (s) or
`max_penetration` (m); `[contact.pairs."a/b"]` tables accept the same keys and override the
global values field by field for one pair of geoms.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from impactlab.record.spec_checks import FieldChecks

PAIR_KEYS = ("restitution", "speed_range", "duration", "max_penetration")


@dataclass(frozen=True)
class ContactTarget:
    """What a calibrated contact must deliver; None means: as the global contact, or default.

    `restitution`: target e. `speed_range`: (lowest, highest) normal impact speed in m/s at
    which e is promised (default: from the experiment, see `impactlab.record.contact_pairs`).
    `duration` in s or `max_penetration` in m: the stiffness (both optional, not both).
    """

    restitution: float | None = None
    speed_range: tuple[float, float] | None = None
    duration: float | None = None
    max_penetration: float | None = None


def contact_target(v: FieldChecks, table: Mapping[str, Any], field: str) -> ContactTarget:
    """The calibration fields of the contact table or of one pair's table."""
    rng = table.get("speed_range")
    if rng is not None:
        rng = v.vector(rng, f"{field}.speed_range", 2)
        if not 0.0 < rng[0] <= rng[1]:
            raise v.fail(f"{field}.speed_range", f"need 0 < v_lo <= v_hi (m/s), got {list(rng)}")
    target = ContactTarget(
        restitution=v.optional(table.get("restitution"), f"{field}.restitution"),
        speed_range=rng,
        duration=v.optional(table.get("duration"), f"{field}.duration", positive=True),
        max_penetration=v.optional(
            table.get("max_penetration"), f"{field}.max_penetration", positive=True
        ),
    )
    if target.duration is not None and target.max_penetration is not None:
        raise v.fail(f"{field}.duration", "give duration or max_penetration, not both")
    return target


def pair_targets(v: FieldChecks, pairs: Any) -> dict[str, ContactTarget]:
    """`[contact.pairs."a/b"]` tables (restitution, speed_range, duration, max_penetration),
    keyed by sorted geom names."""
    if not isinstance(pairs, Mapping):
        raise v.fail("contact.pairs", 'must be a table of "geom1/geom2" = { restitution = e }')
    out = {}
    for key, table in pairs.items():
        field = f"contact.pairs.{key}"
        names = key.split("/")
        if len(names) != 2 or not all(names):
            raise v.fail(field, 'pair keys are two geom names joined by /, e.g. "ball/plane"')
        if not isinstance(table, Mapping) or not table:
            raise v.fail(field, f"must be a table with some of {', '.join(PAIR_KEYS)}")
        unknown = sorted(set(table) - set(PAIR_KEYS))
        if unknown:
            raise v.fail(f"{field}.{unknown[0]}", f"unknown key (known: {', '.join(PAIR_KEYS)})")
        out["/".join(sorted(names))] = contact_target(v, table, field)
    return out
