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
    """A ball bouncing on bumps: episodes with onsets, releases and speeds."""
    return oracle.run(MODELS / "ball_hfield.xml", 1.0, 10)


def explained(run: oracle.Run) -> dict[tuple[str, str, int], str]:
    """A sentence for each episode of e > 1 (the ball grazes the bumps: slow approaches)."""
    return {
        zoo.episode_key(e): "a grazing approach"
        for e in run.episodes
        if e.restitution is not None and e.restitution > 1
    }


def side(run: oracle.Run, record_seconds: float = 1.0, **changes: object) -> zoo.ImpactlabSide:
    changed = dataclasses.replace(run, **changes)
    return zoo.ImpactlabSide(changed, record_seconds, explained(changed))


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
    # and its parties in either order (the normal velocity does not depend on it)
    swapped = dataclasses.replace(first, party1=first.party2, party2=first.party1)
    assert failed(zoo.compare(bouncing, side(bouncing, episodes=(swapped, *rest)), 1.0)) == set()
    assert release_changed_fails(bouncing)


def release_changed_fails(run: oracle.Run) -> bool:
    released = [e for e in run.episodes if e.release_vn is not None]
    assert released
    faster = dataclasses.replace(
        released[0], release_vn=tuple(v + 0.01 for v in released[0].release_vn)
    )
    episodes = tuple(faster if e is released[0] else e for e in run.episodes)
    return "normal speeds at release" in failed(zoo.compare(run, side(run, episodes=episodes), 1.0))


def test_e_outside_bounds_needs_an_explanation(bouncing):
    first, *rest = bouncing.episodes
    approach = first.approach_speed
    assert approach is not None and approach > 0
    bouncy = dataclasses.replace(
        first, release_step=first.onset_step + 5, release_vn=(1.5 * approach,)
    )
    run = dataclasses.replace(bouncing, episodes=(bouncy, *rest))
    assert bouncy.restitution == pytest.approx(1.5)
    others = explained(bouncing)
    others.pop(zoo.episode_key(bouncy), None)
    unexplained = zoo.compare(run, zoo.ImpactlabSide(run, 1.0, others), 1.0)
    assert failed(unexplained) == {"e bounded or explained"}
    sentences = {**others, zoo.episode_key(bouncy): "the joint limit pushed it"}
    blank = {**others, zoo.episode_key(bouncy): " "}
    assert failed(zoo.compare(run, zoo.ImpactlabSide(run, 1.0, blank), 1.0)) == {
        "e bounded or explained"
    }
    explained_run = zoo.compare(run, zoo.ImpactlabSide(run, 1.0, sentences), 1.0)
    assert failed(explained_run) == set()


def test_record_time_goal(bouncing):
    fast = zoo.compare(bouncing, side(bouncing, 1.9), 1.0, max_ratio=2.0)
    slow = zoo.compare(bouncing, side(bouncing, 2.1), 1.0, max_ratio=2.0)
    assert failed(fast) == set() and failed(slow) == {"record time / bare loop"}


def test_strides_agree_on_real_runs_and_not_on_changed_ones(bouncing):
    fine = oracle.run(MODELS / "ball_hfield.xml", 1.0, 1)
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
        ("sdf_torus.xml", {"sdf", "big_mesh"}),  # MuJoCo meshes the SDF: 89,408 faces
        ("sunk_robot.xml", {"touching_t0", "joint_damping"}),
        ("jointed_boxes.xml", set()),
        ("tumbling_box.xml", {"joint_damping"}),
        ("damped_pendulum.xml", {"joint_damping"}),
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
