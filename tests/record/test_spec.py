"""Specs: defaults, overrides, sweep expansion, hashes, the shipped experiments."""

from __future__ import annotations

from pathlib import Path

import pytest
from paths import EXPERIMENTS
from specs import drop, toml

from impactlab.errors import SpecError
from impactlab.record.sweep import load_runs, parse_override

BASE = toml(drop())


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "spec.toml"
    path.write_text(text)
    return path


def test_defaults_fill_omitted_fields(tmp_path):
    (run,) = load_runs(write(tmp_path, BASE))
    assert run.options.integrator == "Euler"
    assert run.contact.solref == (0.02, 1.0)
    assert run.plane.enabled
    assert run.bodies[0].vel == (0.0, 0.0, 0.0)
    assert run.log_every == 1


def test_sweep_is_a_grid_in_key_order(tmp_path):
    text = (
        BASE + '[sweep]\n"ball.mass" = [1.0, 2.0]\n"options.timestep" = [0.001, 0.0005, 0.0001]\n'
    )
    runs = load_runs(write(tmp_path, text))
    assert len(runs) == 6
    assert [r.bodies[0].mass for r in runs] == [1.0] * 3 + [2.0] * 3
    assert [r.options.timestep for r in runs[:3]] == [0.001, 0.0005, 0.0001]
    assert runs[4].sweep_values == {"bodies.ball.mass": 2.0, "options.timestep": 0.0005}
    assert len({r.spec_hash for r in runs}) == 6


def test_override_uses_body_shorthand_and_replaces_a_swept_list(tmp_path):
    text = BASE + '[sweep]\n"ball.mass" = [1.0, 2.0]\n'
    runs = load_runs(write(tmp_path, text), ["ball.mass=5", "options.integrator=RK4"])
    assert [r.bodies[0].mass for r in runs] == [5.0]
    assert runs[0].options.integrator == "RK4"
    (run,) = load_runs(write(tmp_path, BASE), ["ball.pos=[0, 0, 2]"])
    assert run.bodies[0].pos == (0.0, 0.0, 2.0)


def test_hash_is_stable_and_tracks_content(tmp_path):
    (a,) = load_runs(write(tmp_path, BASE))
    (b,) = load_runs(write(tmp_path, BASE))
    (c,) = load_runs(write(tmp_path, BASE), ["ball.mass=1.5"])
    assert a.spec_hash == b.spec_hash != c.spec_hash


@pytest.mark.parametrize(
    ("text", "expected"),
    [("ball.mass=2", ("ball.mass", 2)), ("x=[1, 2]", ("x", [1, 2])), ("i=RK4", ("i", "RK4"))],
)
def test_parse_override(text, expected):
    assert parse_override(text) == expected


def test_parse_override_rejects_missing_equals():
    with pytest.raises(SpecError, match="PATH=VALUE"):
        parse_override("ball.mass")


@pytest.mark.parametrize(
    ("spec", "runs"), [("free_fall", 1), ("drop", 3), ("collision", 1), ("collision_sweep", 4)]
)
def test_shipped_experiments_load(spec, runs):
    loaded = load_runs(EXPERIMENTS / f"{spec}.toml")
    assert len(loaded) == runs
    assert all(r.experiment == spec for r in loaded)


def test_collision_sweep_keeps_the_handout_knob():
    runs = load_runs(EXPERIMENTS / "collision_sweep.toml")
    assert [r.contact.solimp[0] for r in runs] == [0.5, 0.7, 0.9, 0.99]
    assert all(r.contact.solref == (0.001, 1.0) for r in runs)
    assert [(b.mass, b.vel[0]) for b in runs[0].bodies] == [(1.0, 3.0), (2.0, -1.0)]
