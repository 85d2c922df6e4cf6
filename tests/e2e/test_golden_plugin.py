"""The pytest plugin for users' golden tests, run as a user would with pytest's `pytester`:
a test passes against its own golden log, fails in physical terms when the spec's restitution
changes by 0.01, and `--impactlab-update-golden` writes the golden log anew."""

from __future__ import annotations

import re
import tomllib

import pytest
from paths import ROOT

import impactlab
import impactlab.analyze.job
import impactlab.record.planner
import impactlab.record.recorder  # imported here: pytester's in-process runs would import

# numpy and MuJoCo's extension modules again and fail (they load once per process)
from impactlab.testing.golden_physics import PhysicsTolerance, compare_physics

pytestmark = pytest.mark.slow  # the golden plugin's pytest runs

pytest_plugins = ["pytester"]

PLUGIN = "impactlab.testing.pytest_plugin"

# experiments/drop_restitution.toml, shortened: one drop from 1 m, two bounces (0.9 s simulated)
SPEC = (ROOT / "experiments" / "drop_restitution.toml").read_text()
SPEC = SPEC.replace("bounces = 4", "bounces = 2").split("[sweep]")[0]

USER_TEST = """
def test_drop(impactlab_golden):
    impactlab_golden.check("drop.toml", "tests/golden/drop.mcap")

def test_drop_loosely(impactlab_golden):
    impactlab_golden.check(
        "drop.toml", "tests/golden/drop.mcap",
        e=0.05, speed_rel=0.05, height_rel=0.05, energy_rel=0.05, time_s=0.05,
    )
"""


@pytest.fixture(autouse=True)
def no_autoload(monkeypatch: pytest.MonkeyPatch) -> None:
    """The user's pytest loads the plugin by name only, installed entry point or not."""
    monkeypatch.setenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", "1")


def run(pytester: pytest.Pytester, *args: str) -> pytest.RunResult:
    """pytest in the user's project, with the plugin and no other."""
    return pytester.runpytest("-p", PLUGIN, "-p", "no:cacheprovider", *args)


def test_golden_check_passes_fails_in_physical_terms_and_updates(pytester: pytest.Pytester):
    assert tomllib.loads(SPEC)["stop"]["bounces"] == 2 and "sweep" not in tomllib.loads(SPEC)
    pytester.makefile(".toml", drop=SPEC)
    pytester.makepyfile(test_user=USER_TEST)
    golden = pytester.path / "tests" / "golden" / "drop.mcap"

    missing = run(pytester, "-k", "not loosely")
    missing.assert_outcomes(failed=1)
    missing.stdout.fnmatch_lines(
        ["impactlab golden: tests/golden/drop.mcap does not exist*--impactlab-update-golden*"]
    )
    assert not golden.exists()

    written = run(pytester, "--impactlab-update-golden", "-k", "not loosely")
    written.assert_outcomes(passed=1)
    written.stdout.fnmatch_lines(["*impactlab golden logs written*", "tests/golden/drop.mcap: new"])
    assert golden.is_file()
    run(pytester, "-k", "not loosely").assert_outcomes(passed=1)  # against its own golden log

    # the restitution changes by 0.01: the physics differs beyond e's 0.005
    pytester.makefile(".toml", drop=SPEC.replace("restitution = 0.8", "restitution = 0.81"))
    changed = run(pytester)
    changed.assert_outcomes(passed=1, failed=1)  # the loose check still passes
    out = changed.stdout.str()
    assert "the physics of drop.toml differs from tests/golden/drop.mcap (" in out
    before = impactlab.analyze(golden).bounces
    for k in (1, 2):
        m = re.search(
            rf"bounce {k} of ball: e (\d\.\d{{3}}) -> (\d\.\d{{3}}) \(tolerance 0\.005\)", out
        )
        assert m, out
        assert m[1] == f"{before['e_velocity'][k - 1]:.3f}"
        assert abs(float(m[2]) - 0.81) <= 0.005  # the calibrated contact delivers the new e
    assert re.search(r"bounce 1 of ball: v out 3\.\d+ -> 3\.\d+ m/s \(tolerance", out), out
    assert "energy budget: energy lost in contacts" in out
    assert "  contact.restitution: 0.8 -> 0.81" in out
    assert "regenerate: pytest --impactlab-update-golden" in out

    updated = run(pytester, "--impactlab-update-golden", "-k", "not loosely")
    updated.assert_outcomes(passed=1)
    updated.stdout.fnmatch_lines(["*drop.mcap: * physical difference(s) from the previous one"])
    after = impactlab.analyze(golden).bounces["e_velocity"].to_list()
    assert all(abs(e - 0.81) <= 0.005 for e in after) and len(after) == 2
    run(pytester, "-k", "not loosely").assert_outcomes(passed=1)


def test_a_spec_with_several_runs_is_refused_in_one_line(pytester: pytest.Pytester):
    pytester.makefile(".toml", drop=SPEC + '[sweep]\n"ball.pos" = [[0, 0, 1], [0, 0, 2]]\n')
    pytester.makepyfile(test_user=USER_TEST.split("def test_drop_loosely")[0])
    result = run(pytester, "--impactlab-update-golden")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*drop.toml gives 2 runs; a golden log holds one*"])
    assert not (pytester.path / "tests" / "golden").exists()


def test_collisions_are_compared_per_pair(tmp_path):
    """Two balls collide: their post-collision velocities are named v1' and v2'."""
    spec = ROOT / "experiments" / "collision.toml"
    a = impactlab.analyze(impactlab.record(spec, out=tmp_path / "a").paths)
    b = impactlab.analyze(
        impactlab.record(spec, out=tmp_path / "b", overrides=["contact.solref=[0.02, 0.5]"]).paths
    )
    assert compare_physics(a, a).equal
    diff = compare_physics(a, b)
    v1, v1b = a.collisions["v1n_after_mps"][0], b.collisions["v1n_after_mps"][0]
    tol = PhysicsTolerance()
    allowed = tol.speed_abs + tol.speed_rel * max(abs(v1), abs(v1b))
    assert abs(v1 - v1b) > allowed  # a softer, less damped contact: a real change
    line = next(d for d in diff.differences if "v1'" in d)
    m = re.fullmatch(r"collision ball1/ball2: v1' (\S+) -> (\S+) m/s \(tolerance (\S+) m/s\)", line)
    assert m, line
    assert abs(float(m[1]) - v1) < 1e-3 and abs(float(m[2]) - v1b) < 1e-3
    assert float(m[3]) == pytest.approx(allowed, rel=0.01)


def test_the_entry_point_names_the_plugin():
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert pyproject["project"]["entry-points"]["pytest11"] == {"impactlab": PLUGIN}


def test_a_lost_bounce_is_named_with_the_counts(tmp_path):
    doc = {
        "name": "bouncy",
        "options": {"timestep": 0.0005},
        "contact": {"solref": [-20000.0, -5.0]},
        "bodies": {"ball": {"radius": 0.1, "mass": 1.0, "pos": [0.0, 0.0, 1.0]}},
        "stop": {"max_time": 3.0, "bounces": 3},
    }
    three = impactlab.analyze(impactlab.record(doc, out=tmp_path / "a").paths)
    doc["stop"]["bounces"] = 2
    two = impactlab.analyze(impactlab.record(doc, out=tmp_path / "b").paths)
    assert three.runs["n_bounces"][0] == 3 and two.runs["n_bounces"][0] == 2
    diff = compare_physics(three, two).differences
    assert "bounces of ball: 3 -> 2" in diff
    assert "run ended: apex after bounce 3 -> apex after bounce 2" in diff
    assert not any(d.startswith("bounce 1 of ball") for d in diff), diff  # the same first two
