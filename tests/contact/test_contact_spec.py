"""Calibrated contacts in specs: speed ranges (given or from the experiment) and pair tables.

The default range of a ball on the plane runs from its first impact down to the last bounce
that matters (the stop rule's N-th, or the last before max_time, each at (e - 0.005) times the
one before), floored at 0.5 m/s; two balls get their closing speed. A pair's table overrides
the global contact field by field, and the pair is designed for its own speeds.
"""

from __future__ import annotations

import copy
import math

import polars as pl
import pytest

import impactlab
from impactlab.contact import SPEED_FLOOR_MPS
from impactlab.errors import SpecError
from impactlab.record import calibrated_pairs
from impactlab.record.sweep import SpecSweep

G = 9.81
DROP = {
    "name": "d",
    "options": {"timestep": 1e-5},
    "contact": {"restitution": 0.8},
    "bodies": {"ball": {"radius": 0.1, "mass": 1.0, "pos": [0.0, 0.0, 1.0]}},
    "stop": {"max_time": 10.0, "bounces": 4},
}
TWO = {
    "name": "two",
    "options": {"timestep": 1e-5, "gravity": [0.0, 0.0, 0.0]},
    "plane": {"enabled": False},
    "contact": {"restitution": 0.7},
    "bodies": {
        "a": {"radius": 0.1, "mass": 1.0, "pos": [-0.5, 0.0, 0.0], "vel": [3.0, 0.0, 0.0]},
        "b": {"radius": 0.05, "mass": 2.0, "pos": [0.5, 0.0, 0.0], "vel": [-1.0, 0.0, 0.0]},
    },
    "stop": {"max_time": 1.0, "separation": 0.1},
}


def doc(base: dict, **changes) -> dict:
    """A copy of a spec document with dotted paths changed."""
    out = copy.deepcopy(base)
    for path, value in changes.items():
        node = out
        keys = path.split("__")
        for k in keys[:-1]:
            node = node.setdefault(k, {})
        node[keys[-1]] = value
    return out


def pairs(document: dict):
    (run,) = SpecSweep.of(document, "<test>").iter_runs()
    return {f"{p.geom1}/{p.geom2}": p.params for p in calibrated_pairs(run)}


def test_default_range_runs_to_the_stop_rules_last_bounce():
    v1 = math.sqrt(2 * G * 0.9)
    (p,) = pairs(DROP).values()
    assert p.speed_range_mps == pytest.approx((v1 * 0.795**3, v1), rel=1e-12)
    # no bounce limit: the ball bounces until it rests, the range goes down to the floor
    (p,) = pairs(doc(DROP, stop__bounces=None, stop__at_rest=True)).values()
    assert p.speed_range_mps == pytest.approx((SPEED_FLOOR_MPS, v1))
    # the time limit: only the impacts before it matter (at 0.43 s, 1.11 s, 1.65 s)
    (p,) = pairs(doc(DROP, stop__bounces=None, stop__max_time=1.2)).values()
    assert p.speed_range_mps == pytest.approx((v1 * 0.795, v1))
    (p,) = pairs(doc(DROP, stop__bounces=None, stop__max_time=1.0)).values()
    assert p.speed_range_mps == pytest.approx((v1, v1))
    # a first impact slower than the floor: one speed
    (p,) = pairs(doc(DROP, bodies__ball__pos=[0.0, 0.0, 0.105])).values()
    assert p.speed_range_mps == pytest.approx((math.sqrt(2 * G * 0.005),) * 2)


def test_given_ranges_and_two_balls():
    (p,) = pairs(doc(DROP, contact__speed_range=[1.0, 6.0])).values()
    assert p.speed_range_mps == (1.0, 6.0)
    got = pairs(TWO)
    assert list(got) == ["a/b"] and got["a/b"].speed_range_mps == (4.0, 4.0)
    assert got["a/b"].gravity_mps2 == 0.0 and got["a/b"].max_penetration_m <= 0.02 * 0.05
    got = pairs(doc(TWO, contact__pairs={"b/a": {"speed_range": [2.0, 5.0]}}))
    assert got["a/b"].speed_range_mps == (2.0, 5.0) and got["a/b"].restitution == 0.7
    (p,) = pairs(doc(DROP, options__integrator="RK4")).values()
    assert p.integrator == "RK4"


def test_a_pair_table_takes_everything_the_global_contact_does():
    spec = doc(
        DROP,
        bodies__fast={"radius": 0.1, "mass": 1.0, "pos": [1.0, 0.0, 0.11], "vel": [0, 0, -5.2]},
        contact__max_penetration=0.001,
        contact__pairs={
            "fast/plane": {"restitution": 0.9, "duration": 0.002},
            "plane/ball": {"speed_range": [1.0, 4.5]},
            "ball/fast": {"speed_range": [1.0, 2.0]},  # they do not approach: say how fast
        },
    )
    got = pairs(spec)
    ball, fast = got["plane/ball"], got["plane/fast"]
    assert ball.restitution == 0.8 and ball.speed_range_mps == (1.0, 4.5)
    assert ball.max_penetration_m <= 0.001  # the global bound, the pair's own speeds
    assert fast.restitution == 0.9 and fast.duration_s == pytest.approx(0.002, rel=1e-6)
    assert fast.speed_range_mps[1] == pytest.approx(math.sqrt(5.2**2 + 2 * G * 0.01))
    # two balls hit at different speeds: each pair its own
    spec = doc(spec, contact__pairs={"ball/fast": {"speed_range": [1.0, 2.0]}})
    got = pairs(spec)
    assert got["plane/fast"].speed_range_mps[1] > 5.2 > got["plane/ball"].speed_range_mps[1]
    assert got["plane/fast"].max_penetration_m <= 0.001


BAD = [
    ({"contact__speed_range": [3.0, 1.0]}, "contact.speed_range", "v_lo <= v_hi"),
    ({"contact__speed_range": [0.0, 1.0]}, "contact.speed_range", "0 < v_lo"),
    ({"contact__speed_range": "fast"}, "contact.speed_range", "list of 2"),
    ({"contact__speed_range": [1.0, 2.0, 3.0]}, "contact.speed_range", "list of 2"),
    ({"contact__impact_speed": 3.0}, "contact.impact_speed", "speed_range"),
    ({"contact__speed_range": [1e-9, 3.0]}, "contact.speed_range", "outside what the designer"),
    (
        {"contact__pairs": {"ball/plane": {"speed_range": [2.0, 1.0]}}},
        "contact.pairs.ball/plane.speed_range",
        "v_lo <= v_hi",
    ),
    (
        {"contact__pairs": {"ball/plane": {"impact_speed": 2.0}}},
        "contact.pairs.ball/plane.impact_speed",
        "unknown key",
    ),
    ({"contact__pairs": {"ball/plane": {}}}, "contact.pairs.ball/plane", "some of"),
    (
        {"contact__pairs": {"ball/plane": {"duration": 0.001, "max_penetration": 0.001}}},
        "contact.pairs.ball/plane.duration",
        "not both",
    ),
    (
        {"contact__restitution": None, "contact__pairs": {"ball/plane": {"duration": 0.001}}},
        "contact.pairs.ball/plane",
        "no restitution",
    ),
    ({"contact__pairs": {"ball/ball": {"restitution": 0.5}}}, "ball/ball", "two geoms"),
    ({"contact__pairs": {"ball/floor": {"restitution": 0.5}}}, "ball/floor", "no geom"),
    (
        {"bodies__b": {"radius": 0.1, "mass": 1.0, "pos": [1.0, 0.0, 1.0]}},
        "contact.restitution",
        'do not approach; set contact.speed_range .or contact.pairs."b/ball".speed_range',
    ),
    ({"options__timestep": 1e-3}, "contact.restitution", "timestep <= "),
    (
        {"contact__pairs": {"ball/plane": {"speed_range": [0.01, 5.0]}}},
        "contact.pairs.ball/plane.speed_range",
        "timestep <= ",
    ),
]


@pytest.mark.parametrize(("changes", "field", "words"), BAD)
def test_bad_contact_fields_name_the_field(changes, field, words):
    with pytest.raises(SpecError, match=words) as info:
        pairs(doc(DROP, **changes))
    assert field in str(info.value)


@pytest.mark.slow
def test_each_pair_holds_its_own_target_in_a_recording(tmp_path):
    """Two balls on one plane, one hit at 5.2 m/s: each pair is designed for its own speeds
    and table, and holds its e and penetration bound in the logs (every step logged)."""
    spec = doc(
        DROP,
        contact__restitution=0.5,
        bodies__ball__pos=[0.0, 0.0, 0.4],
        bodies__fast={"radius": 0.05, "mass": 0.2, "pos": [1.0, 0.0, 0.06], "vel": [0, 0, -5.2]},
        contact__pairs={
            "fast/plane": {"restitution": 0.9, "max_penetration": 0.0008},
            "ball/fast": {"speed_range": [1.0, 2.0]},
        },
        stop__bounces=1,
    )
    got = pairs(spec)
    result = impactlab.analyze(impactlab.record(spec, out=tmp_path).paths)
    first = result.bounces.filter(pl.col("bounce") == 1).sort("body")
    assert first["body"].to_list() == ["ball", "fast"]
    assert first["e_velocity"].to_list() == pytest.approx([0.5, 0.9], abs=0.005)
    ball, fast = first.row(0, named=True), first.row(1, named=True)
    assert -fast["v_in_mps"] == pytest.approx(5.2, rel=0.01)
    assert got["plane/fast"].speed_range_mps[1] == pytest.approx(-fast["v_in_mps"], rel=1e-3)
    assert fast["max_penetration_m"] <= 0.0008
    assert got["plane/ball"].speed_range_mps[1] == pytest.approx(-ball["v_in_mps"], rel=1e-3)
    assert ball["max_penetration_m"] <= 0.02 * 0.1
