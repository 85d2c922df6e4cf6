"""MuJoCo's own warnings: a run that trips one is `unstable`, its outcome names the warning,
the job exits 1, the log keeps only the rows before it, and no MUJOCO_LOG.TXT appears."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from specs import drop, toml

from impactlab.cli import main
from impactlab.logs.load import load_log

DROP = toml(drop(max_time=0.5))

# (override, the warning, the step that raises it)
HUGE = [
    ("ball.vel=[0, 0, 1e300]", "mjWARN_BADQVEL", 0),
    ("ball.angvel=[0, 0, 1e300]", "mjWARN_BADQVEL", 0),
    ("ball.pos=[0, 0, 1e300]", "mjWARN_BADQPOS", 0),
    ("ball.pos=[1e300, 0, 1]", "mjWARN_BADQPOS", 0),
    # through the plane in one step: the contact's acceleration is huge at step 1
    ("ball.vel=[0, 0, -1e9]", "mjWARN_BADQACC", 1),
]


@pytest.mark.filterwarnings("error::RuntimeWarning")  # no overflow in our own code
@pytest.mark.parametrize(("override", "warning", "step"), HUGE, ids=[h[0] for h in HUGE])
def test_huge_values_are_unstable_runs(tmp_path, monkeypatch, capsys, override, warning, step):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "spec.toml").write_text(DROP)
    code = main(["record", "spec.toml", "-o", "logs", "--set", override])
    out, err = capsys.readouterr()
    assert code == 1, (out, err)
    (path,) = (tmp_path / "logs").glob("*.mcap")
    log = load_log(path)
    assert log.outcome == "unstable"
    reason = log.meta["reason"]
    assert reason.startswith(f"MuJoCo warning at t = {step * 0.001:g} s (step {step}): {warning}")
    assert "The simulation is unstable" in reason
    assert f"warning: {path.stem}: unstable: MuJoCo warning" in out
    # only the rows before the warning: never MuJoCo's reset state
    ball = log.bodies["ball"]
    assert ball.height == step
    if step:
        assert ball["z"][0] == 1.0 and ball["vz"][0] == -1e9
    assert sorted(p.name for p in tmp_path.iterdir()) == ["logs", "spec.toml"]  # no MUJOCO_LOG


def test_a_gravity_the_log_cannot_hold_is_refused_before_anything_runs(tmp_path, capsys):
    """Gravity 1e300 m/s^2: its log's metadata would be refused by the reader (one contract):
    one line naming the key, exit 2, nothing written."""
    (tmp_path / "spec.toml").write_text(DROP)
    out = tmp_path / "logs"
    code = main(
        [
            "record",
            str(tmp_path / "spec.toml"),
            "-o",
            str(out),
            "--set",
            "options.gravity=[0, 0, -1e300]",
        ]
    )
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1
    assert "the log could not hold this run: gravity:" in err[0]
    assert not out.exists() or not list(out.iterdir())


def test_a_warning_in_the_last_step_of_a_chunk(tmp_path, capsys):
    """Gravity pushes the speed past MuJoCo's 1e10 limit in step 999, the last of the first
    chunk (1000 steps): found although the next chunk starts again from MuJoCo's reset state.
    The speed after k steps of 1 ms is v0 + k g dt: with g = 1e6 m/s^2 (the largest a log
    holds) and v0 = 1e10 - 998.5 g dt it passes 1e10 first when k = 999."""
    spec = tmp_path / "fly.toml"
    spec.write_text(
        DROP.replace("timestep = 0.001", "timestep = 0.001\ngravity = [0.0, 0.0, 1e6]")
        .replace("pos = [0.0, 0.0, 1.0]", "pos = [0.0, 0.0, 0.0]\nvel = [0.0, 0.0, 9999001500.0]")
        .replace("max_time = 0.5", "max_time = 1.5")
        + "[plane]\nenabled = false\n"
    )
    assert main(["record", str(spec), "-o", str(tmp_path / "logs")]) == 1
    (path,) = (tmp_path / "logs").glob("*.mcap")
    log = load_log(path)
    assert "(step 999): mjWARN_BADQVEL" in log.meta["reason"]
    ball = log.bodies["ball"]
    assert ball.height == 999
    assert np.all(np.diff(ball["vz"].to_numpy()) > 0)  # the speed only grew: no reset inside
    capsys.readouterr()


def test_other_runs_of_the_batch_complete(tmp_path, capsys):
    """One run of a batched sweep trips a warning; the other runs of its rollout are whole."""
    spec = tmp_path / "spec.toml"
    spec.write_text(DROP + '[sweep]\n"ball.vel" = [[0, 0, 0], [0, 0, 1e300], [0, 0, 1]]\n')
    assert main(["record", str(spec), "-o", str(tmp_path / "logs")]) == 1
    out = capsys.readouterr().out
    assert "3 run(s) written" in out and "1 unstable" in out
    outcomes = sorted(load_log(p).outcome for p in (tmp_path / "logs").glob("*.mcap"))
    assert outcomes == ["completed", "completed", "unstable"]
    for path in (tmp_path / "logs").glob("*.mcap"):
        log = load_log(path)
        if log.outcome == "completed":
            assert log.bodies["ball"].height == 501


# ---- what is not an instability ----------------------------------------------------------------


def _record_model(tmp_path, capsys, xml: str, duration: str):
    """Record the MJCF text `xml` for `duration` s (the command must exit 0); its one log."""
    model = tmp_path / "model.xml"
    model.write_text(xml)
    assert main(["record", str(model), "--duration", duration, "-o", str(tmp_path / "logs")]) == 0
    capsys.readouterr()
    (path,) = (tmp_path / "logs").glob("*.mcap")
    return load_log(path)


COARSE_PENDULUM = """<mujoco><option timestep="0.02"/><worldbody>
  <body name="l1"><joint type="hinge" axis="1 0 0"/><geom pos="0 .5 0" size=".15" mass="1"/>
    <body pos="0 .5 0"><joint type="hinge" axis="1 0 0"/><geom pos="0 .5 0" size=".15" mass="1"/>
      <body pos="0 .5 0"><joint type="hinge" axis="1 0 0"/>
        <geom pos="0 .5 0" size=".15" mass="1"/></body></body></body>
</worldbody></mujoco>"""


def test_the_bounded_drift_of_a_coarse_step_is_not_an_instability(tmp_path, capsys):
    """A triple pendulum released level with semi-implicit Euler at 20 ms (brax's): the
    energy no force explains swings to a tenth of what the pendulum holds and back, by a
    small part of it per step; the run goes on to its end, as MuJoCo's does."""
    log = _record_model(tmp_path, capsys, COARSE_PENDULUM, "1")
    assert log.outcome == "completed" and log.meta["reason"] == "time limit 1 s"
    kinetic = log.energy["kinetic"].to_numpy()
    total = log.energy["total"].to_numpy()  # no force but gravity does work
    drift = total - total[0]
    assert np.abs(drift).max() > 0.1 * kinetic.max()  # not small: a level would stop it
    assert np.abs(np.diff(drift)).max() < 0.05 * kinetic.max()  # but small per step


OVERLAPPING = """<mujoco><worldbody>
  <body><joint type="hinge" axis="1 0 0"/><geom size=".1"/>
    <body><joint type="hinge" axis="1 0 0"/><geom size=".1"/>
      <body><joint type="hinge" axis="1 0 0"/><geom size=".1"/></body></body></body>
</worldbody></mujoco>"""


def test_bodies_overlapping_at_the_start_are_not_an_instability(tmp_path, capsys):
    """Three spheres built in one place (mujoco_warp's actuation test model): the first and
    the third touch, 0.2 m deep (a whole radius past stop.max_penetration's bound) from
    step 0. MuJoCo runs it; so does the recorder, whose bound counts from that depth."""
    log = _record_model(tmp_path, capsys, OVERLAPPING, "0.2")
    assert log.outcome == "completed"
    deepest = log.contacts["penetration"].max()
    assert deepest == pytest.approx(0.2, abs=1e-6)


def test_a_residual_that_comes_back_is_not_growth_one_above_its_highest_is():
    """The energy rule on the budget alone (no body, so the energy is the kinetic column): a
    limit does 300 J in the first step and 290 J appear (residual -10 J); later the residual
    drops by 46 J and comes back by 42 J (a limit impulse RK4 books a step early, as in
    Gymnasium's ant): no new energy. Then 20 J appear with no work, 6 J above the highest
    residual so far, under 0.1 of the 306 J in play; then 40 J more: unstable at that step."""
    from impactlab.record.budget import WORK_KINDS
    from impactlab.record.stop import Chunk, _Residual

    kinetic = np.array([0.0, 290, 290, 290, 244, 286, 286, 306, 306, 346, 346])
    work = np.zeros((kinetic.size, len(WORK_KINDS)))
    work[0, WORK_KINDS.index("limits")] = 300.0  # the step from row 0 to row 1
    rule = _Residual(0, [], np.zeros((0, 3)), 0.1, 0.01, in_play=1.0)

    def feed(rows: slice):
        chunk = Chunk(kinetic[rows, None], rows.start, None, (None, None), [], work[rows])
        return rule.update(chunk)

    assert feed(slice(0, 4)) is None and feed(slice(4, 8)) is None  # chunks carry the state
    verdict = feed(slice(8, 11))
    assert verdict is not None and verdict.last_step == 9 and verdict.outcome == "unstable"
    assert verdict.reason.startswith("energy grew by 40 J in one step that no force explains")
    assert "(bound 0.1 x 306 J, the energy in play) at t = 0.09 s" in verdict.reason


def test_a_compiler_warning_is_the_outcomes_not_a_python_warning(tmp_path, capsys):
    """Three slide joints in one plane: MuJoCo's compiler warns of a singular inertia (as a
    Python warning) and its first step raises mjWARN_INERTIA. The run is unstable at step 0
    naming it; no Python warning, printed with a source line of impactlab's, leaks out."""
    xml = tmp_path / "slides.xml"
    xml.write_text(
        '<mujoco><worldbody><body><joint type="slide" axis="1 0 0"/>'
        '<joint type="slide" axis="0 1 0"/><joint type="slide" axis="1 1 0"/>'
        '<geom type="box" size=".05 .05 .05" mass="1"/>'
        "</body></worldbody></mujoco>"
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code = main(["record", str(xml), "-o", str(tmp_path / "logs"), "--duration", "0.1"])
    assert code == 1
    assert [str(w.message) for w in caught] == []
    assert "(step 0): mjWARN_INERTIA" in capsys.readouterr().out


def test_mujocos_python_warnings_on_saving_a_model_are_kept(tmp_path, capsys):
    """A model with an include is kept in the log as MuJoCo saves it (`MjSpec.to_xml`), which
    warns of a deprecated attribute (`settotalmass`, MuJoCo 4) as a Python warning: kept with
    MuJoCo's messages, never printed with a source line of impactlab's."""
    (tmp_path / "part.xml").write_text(
        '<mujoco><worldbody><body pos="0 0 1"><freejoint/><geom type="sphere" size=".1"/>'
        "</body></worldbody></mujoco>"
    )
    xml = tmp_path / "main.xml"
    xml.write_text('<mujoco><compiler settotalmass="2"/><include file="part.xml"/></mujoco>')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code = main(["record", str(xml), "-o", str(tmp_path / "logs"), "--duration", "0.01"])
    assert code == 0, capsys.readouterr()
    assert [str(w.message) for w in caught] == []
