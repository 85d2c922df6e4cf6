"""The zoo's comparison, model discovery and classes, on real oracle runs."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import mujoco
import numpy as np
import oracle
import pytest
import zoo

MODELS = Path(__file__).resolve().parent / "models"


@pytest.fixture(scope="module")
def bouncing() -> oracle.Run:
    """The limbs of limits_violated.xml hit the floor: episodes with onsets and speeds."""
    return oracle.run(MODELS / "limits_violated.xml", 0.6, 10)


def side(run: oracle.Run, **changes: object) -> zoo.ImpactlabSide:
    return zoo.ImpactlabSide(run=dataclasses.replace(run, **changes), record_seconds=1.0)


def failed(checks: list[zoo.Check]) -> set[str]:
    return {c.name for c in checks if c.passed is False}


def test_identical_results_pass_every_check(bouncing):
    checks = zoo.compare(bouncing, side(bouncing), bare_seconds=1.0)
    assert failed(checks) == set()
    names = {c.name for c in checks}
    assert {f"work {k}" for k in oracle.WORK_KINDS} <= names
    assert {"kinetic energy", "potential energy", "residual", "contact onsets"} <= names
    (timing,) = [c for c in checks if c.name == "record time / bare loop"]
    assert timing.passed is None  # measured, no goal without max_ratio


def test_an_energy_off_by_more_than_the_tolerance_fails(bouncing):
    kinetic = bouncing.kinetic.copy()
    kinetic[3] += 1e-6 * bouncing.energy_scale
    assert failed(zoo.compare(bouncing, side(bouncing, kinetic=kinetic), 1.0)) == {"kinetic energy"}
    kinetic[3] = bouncing.kinetic[3] + 1e-12 * bouncing.energy_scale  # within 1e-9 of the scale
    assert failed(zoo.compare(bouncing, side(bouncing, kinetic=kinetic), 1.0)) == set()


def test_a_wrong_or_missing_work_kind_fails(bouncing):
    work = dict(bouncing.work)
    work["damper"] = work["damper"] + 0.01
    assert failed(zoo.compare(bouncing, side(bouncing, work=work), 1.0)) == {"work damper"}
    del work["damper"]
    assert failed(zoo.compare(bouncing, side(bouncing, work=work), 1.0)) == {"work damper"}
    residual = bouncing.residual.copy()
    residual[-1] = np.nan
    assert failed(zoo.compare(bouncing, side(bouncing, residual=residual), 1.0)) == {"residual"}


def test_other_logged_steps_fail(bouncing):
    fewer = {
        f: getattr(bouncing, f)[:-1] for f in ("step", "time", "kinetic", "potential", "residual")
    }
    checks = zoo.compare(bouncing, side(bouncing, **fewer), 1.0)
    assert "logged steps" in failed(checks)
    assert "kinetic energy" not in {c.name for c in checks}  # not compared step by step


def test_episodes_missing_extra_or_off_fail(bouncing):
    assert len(bouncing.episodes) >= 2
    first, *rest = bouncing.episodes
    assert "contact onsets" in failed(
        zoo.compare(bouncing, side(bouncing, episodes=tuple(rest)), 1.0)
    )
    late = dataclasses.replace(first, onset_step=first.onset_step + 1)
    assert "contact onsets" in failed(
        zoo.compare(bouncing, side(bouncing, episodes=(late, *rest)), 1.0)
    )
    assert first.onset_vn is not None
    slower = dataclasses.replace(first, onset_vn=tuple(v * 0.99 for v in first.onset_vn))
    got = failed(zoo.compare(bouncing, side(bouncing, episodes=(slower, *rest)), 1.0))
    assert "normal speeds at onset" in got
    # the contacts of one pair may come in another order
    shuffled = dataclasses.replace(first, onset_vn=tuple(reversed(first.onset_vn)))
    assert failed(zoo.compare(bouncing, side(bouncing, episodes=(shuffled, *rest)), 1.0)) == set()


def test_e_outside_bounds_needs_an_explanation(bouncing):
    first, *rest = bouncing.episodes
    approach = first.approach_speed
    assert approach is not None and approach > 0
    bouncy = dataclasses.replace(
        first, release_step=first.onset_step + 5, release_vn=(1.5 * approach,)
    )
    run = dataclasses.replace(bouncing, episodes=(bouncy, *rest))
    assert bouncy.restitution == pytest.approx(1.5)
    key = (bouncy.party1, bouncy.party2, bouncy.onset_step)
    unexplained = zoo.compare(run, zoo.ImpactlabSide(run, 1.0), 1.0)
    assert failed(unexplained) == {"e bounded or explained"}
    explained = zoo.compare(
        run, zoo.ImpactlabSide(run, 1.0, {key: "the joint limit pushed it"}), 1.0
    )
    assert failed(explained) == set()


def test_record_time_goal(bouncing):
    fast = zoo.compare(bouncing, zoo.ImpactlabSide(bouncing, 1.9), 1.0, max_ratio=2.0)
    slow = zoo.compare(bouncing, zoo.ImpactlabSide(bouncing, 2.1), 1.0, max_ratio=2.0)
    assert failed(fast) == set() and failed(slow) == {"record time / bare loop"}


def test_strides_agree_on_real_runs_and_not_on_changed_ones(bouncing):
    fine = oracle.run(MODELS / "limits_violated.xml", 0.6, 1)
    assert zoo.strides_agree(fine, bouncing)
    residual = bouncing.residual.copy()
    residual[2] += 1e-6
    assert not zoo.strides_agree(fine, dataclasses.replace(bouncing, residual=residual))
    assert not zoo.strides_agree(
        fine, dataclasses.replace(bouncing, episodes=bouncing.episodes[1:])
    )


def test_include_tree_finds_a_file_beside_its_includer(tmp_path):
    (tmp_path / "parts").mkdir()
    (tmp_path / "top.xml").write_text(
        '<mujoco><!-- <include file="gone.xml"/> --><include file="parts/a.xml"/></mujoco>'
    )
    (tmp_path / "parts" / "a.xml").write_text('<mujoco><include file="b.xml"/></mujoco>')
    (tmp_path / "parts" / "b.xml").write_text("<mujoco/>")
    tree = zoo.include_tree(tmp_path / "top.xml")
    assert [(p.name, depth, beside) for p, depth, beside in tree] == [
        ("a.xml", 1, False),
        ("b.xml", 2, True),
    ]
    models = zoo._models_in(sorted(tmp_path.rglob("*.xml")), "test", tmp_path)
    assert [(m.name, m.nested_include) for m in models] == [("top.xml", True)]


def test_find_models_lists_the_own_models_and_not_their_parts():
    models, _ = zoo.find_models()
    own = {m.name for m in models if m.package == zoo.OWN}
    assert "models/nested_include/scene.xml" in own
    assert "models/humanoids_10.xml" in own
    assert not any("/parts/" in name or "/common/" in name for name in own)


@pytest.mark.parametrize(
    ("model", "expected"),
    [
        ("massless_foot.xml", {"massless_child"}),
        ("stacked_boxes.xml", {"touching_t0"}),
        ("nested_include/scene.xml", {"nested_include", "joint_damping"}),
        ("limits_violated.xml", {"qpos0_outside_limits", "joint_damping"}),
        ("boxes_100.xml", {"many_free_bodies"}),
        ("humanoids_10.xml", {"several_humanoids", "joint_damping", "actuators"}),
        ("flexcomp_drop.xml", {"flex"}),
        ("ball_hfield.xml", {"hfield"}),
        ("mocap_platform.xml", {"mocap"}),
        (
            "all_forces.xml",
            {"tendons", "equality", "fluid", "gravcomp", "actuators", "joint_damping"},
        ),
    ],
)
def test_model_classes(model, expected):
    path = MODELS / model
    m, d = oracle.load(path)
    mujoco.mj_forward(m, d)
    nested = any(beside for _, _, beside in zoo.include_tree(path))
    assert set(zoo.model_classes(zoo.ZooModel(path, zoo.OWN, model, nested), m, d)) == expected
