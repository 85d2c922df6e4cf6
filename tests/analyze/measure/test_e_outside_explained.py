"""An e outside [0, 1] is explained by the budget of its episode (issue 35).

A ball rests 1.5 mm above a paddle on a slide joint that a constant 30 N actuator lifts: the
paddle catches the ball and carries it until the joint's upper limit stops the paddle, so
the ball leaves far faster than it arrived. The collision's note quotes the works measured
over the contact: the actuator's is F dq of the paddle, gravity's -m g dz of both bodies.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.analyze.measure.episodes import e_note
from impactlab.cli import main
from impactlab.logs.load import load_log
from impactlab.logs.messages import WORK_FIELDS

PUSH_N = 30.0
PADDLE = f"""<mujoco>
  <option timestep="0.001"/>
  <worldbody>
    <body name="paddle" pos="0 0 -0.1">
      <joint name="lift" type="slide" axis="0 0 1" range="0 0.2" limited="true"/>
      <geom name="pad" type="box" size="0.1 0.1 0.01" mass="1"/>
    </body>
    <body name="ball" pos="0 0 -0.0585">
      <freejoint/><geom name="ball" type="sphere" size="0.03" mass="0.1"/>
    </body>
  </worldbody>
  <actuator>
    <general name="push" joint="lift" biastype="affine" biasprm="{PUSH_N} 0 0"/>
  </actuator>
</mujoco>"""


def _number(note: str, pattern: str) -> float:
    """The number of J after `pattern` in a note (3 significant digits: rel 5e-3)."""
    found = re.search(pattern + r" ([-+]?[\d.]+(?:e[-+]?\d+)?) J", note)
    assert found is not None, (pattern, note)
    return float(found.group(1))


def test_a_paddle_driven_into_a_ball_gets_its_e_above_one_from_the_actuator(tmp_path: Path):
    model = tmp_path / "paddle.xml"
    model.write_text(PADDLE)
    assert main(["record", str(model), "-o", str(tmp_path), "--duration", "0.3"]) == 0
    (path,) = tmp_path.glob("*.mcap")
    log = load_log(path)
    analysis = analyze_run(log)
    (row,) = analysis.collisions.iter_rows(named=True)
    (episode,) = log.impacts.iter_rows(named=True)
    e = -episode["v_out_mps"] / episode["v_in_mps"]
    assert e > 1.5  # carried up: it leaves faster than it came
    assert row["e_velocity"] == pytest.approx(e, rel=1e-12)
    note = row["note"]
    assert note.startswith(f"e_velocity {e:.3g} is outside [0, 1]")
    assert analysis.intervals["e_note"].to_list() == [note]  # one definition, both tables

    t0, t1 = (float(x) for x in re.findall(r"From ([\d.]+) to ([\d.]+) s", note)[0])
    assert t0 == pytest.approx(episode["onset_ns"] / 1e9) and t1 == pytest.approx(
        episode["release_ns"] / 1e9
    )  # logged every step: the window is the contact's

    def z(body: str, t: float) -> float:
        frame = log.bodies[body].filter(pl.col("t_ns") == round(t * 1e9))
        return float(frame["z"].item())

    def booked(kind: str) -> float:
        at = log.work.filter(pl.col("t_ns").is_in([round(t0 * 1e9), round(t1 * 1e9)]))
        return float(at[kind][1] - at[kind][0])

    lift = z("paddle", t1) - z("paddle", t0)
    assert _number(note, "actuators") == pytest.approx(booked("actuators"), rel=5e-3)
    # MuJoCo's force times the logged lift, to what one Euler step of 2 m/s moves (0.5 %)
    assert _number(note, "actuators") == pytest.approx(PUSH_N * lift, rel=0.01)
    g = 9.81
    fall = 1.0 * (z("paddle", t1) - z("paddle", t0)) + 0.1 * (z("ball", t1) - z("ball", t0))
    assert _number(note, "gravity") == pytest.approx(-g * fall, rel=5e-3)  # m g . dx exactly
    assert _number(note, "limits") == pytest.approx(booked("limits"), rel=5e-3)
    assert _number(note, "limits") < 0  # the upper limit stops the paddle
    own = episode["work_compression_J"] + episode["work_restitution_J"]
    assert _number(note, "normal force did") == pytest.approx(own, rel=5e-3)
    assert "other contacts" not in note  # nothing else touches either body
    assert note.endswith("the largest input: actuators")


EPISODE = {
    "start_t_ns": 2_000_000,
    "end_t_ns": 4_000_000,
    "v_in_mps": -0.5,
    "v_out_mps": 0.25,
    "work_c_J": -0.2,
    "work_r_J": 0.05,
    "work_f_J": -0.01,
    "e_energy": 0.5,  # sqrt(0.05 / 0.2)
}


def _budget(**works: list[float]) -> dict[str, np.ndarray]:
    zero = [0.0] * 5
    every = {k: works.get(k, zero) for k in (*WORK_FIELDS, "gravity")}
    return {k: np.array(v, dtype=float) for k, v in every.items()}


T_NS = np.arange(5) * 1_000_000


def test_the_note_quotes_each_kinds_work_over_the_contact_and_the_largest_input():
    episode = EPISODE | {"v_out_mps": -0.1}  # still approaching at the release: e < 0
    budget = _budget(
        contact_normal=[0, 0, 0, -0.15, -0.05],  # this contact's -0.15 J and another's +0.1 J
        contact_friction=[0, 0, 0, 0, -0.01],
        actuators=[0, 0, 1.0, 1.5, 2.0],
        damping=[0, 0, 0, -0.2, -0.3],
        gravity=[0, 0, 0, 0, float("nan")],  # a damaged value is not quoted as a work
    )
    note = e_note(episode, T_NS, budget)
    assert note == (
        "e_velocity -0.2 is outside [0, 1]: a ratio of the contact point's speeds, not a "
        "restitution. From 0.002 to 0.004 s this contact's normal force did -0.15 J "
        "(e_energy 0.5); the model's other forces: actuators +1 J, damping -0.3 J, "
        "other contacts +0.1 J; the largest input: actuators"
    )


def test_without_work_from_any_other_force_the_note_says_no_energy_came_in():
    note = e_note(
        EPISODE | {"v_out_mps": 0.75},
        T_NS,
        _budget(contact_normal=[0, 0, 0, -0.15, -0.15], contact_friction=[0, 0, 0, 0, -0.01]),
    )
    assert "the model's other forces: none did work; no force put energy in" in note
    assert note.startswith("e_velocity 1.5 is outside [0, 1]")


def test_a_log_without_a_budget_still_gets_a_note_without_numbers_it_lacks():
    empty = {k: np.empty(0) for k in (*WORK_FIELDS, "gravity")}
    note = e_note(EPISODE | {"v_out_mps": 0.75}, np.empty(0, np.int64), empty)
    assert "Over the contact this contact's normal force did -0.15 J" in note
    assert note.endswith(
        "the model's other forces: not in the log; where the energy came from is unknown"
    )


def test_a_damaged_work_is_named_unknown_not_ruled_out():
    budget = _budget(
        contact_normal=[0, 0, 0, -0.15, -0.15],
        contact_friction=[0, 0, 0, 0, -0.01],
        actuators=[0, 0, 0, 0, float("nan")],
    )
    note = e_note(EPISODE | {"v_out_mps": 0.75}, T_NS, budget)
    assert note.endswith("none did work; no force quoted put energy in; unknown: actuators")
