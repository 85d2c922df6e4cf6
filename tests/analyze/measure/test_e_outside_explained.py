"""An e outside [0, 1] is explained by the budget of its episode (issue 35).

A ball rests 1.5 mm above a paddle on a slide joint that a constant 30 N actuator lifts: the
paddle catches the ball and carries it until the joint's upper limit stops the paddle, so
the ball leaves far faster than it arrived. The collision's note quotes the works measured
over the contact: the actuator's is F dq of the paddle, gravity's -m g dz of both bodies.
"""

from __future__ import annotations

import re
from pathlib import Path

import polars as pl
import pytest

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.cli import main
from impactlab.logs.load import load_log

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
