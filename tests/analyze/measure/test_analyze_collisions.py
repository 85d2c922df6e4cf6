"""Collision analysis on a zero-gravity ball-ball run with a known contact."""

from __future__ import annotations

import numpy as np
import pytest
from known import COLLISION_SPEC, M1, M2, V1, V2, ZETA, schwager_poeschel

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.logs.load import load_log
from impactlab.physics import collision_after


@pytest.fixture(scope="module")
def hit(record_spec):
    (path,) = record_spec("known_collision", COLLISION_SPEC)
    return analyze_run(load_log(path))


@pytest.mark.slow
def test_momentum_conserved(hit):
    row = hit.collisions.row(0, named=True)
    assert row["complete"]
    assert row["momentum_rel_change"] < 1e-9
    assert row["px_after_Ns"] == pytest.approx(M1 * V1 + M2 * V2, abs=1e-9)


def test_restitution_and_energy_loss(hit):
    """e within 0.01 of the closed form; KE loss = (1 - e^2) m1 m2 (v1 - v2)^2 / (2 (m1 + m2))."""
    row = hit.collisions.row(0, named=True)
    assert abs(row["e_velocity"] - schwager_poeschel(ZETA)) < 0.01
    expected = (1 - row["e_velocity"] ** 2) * M1 * M2 * (V1 - V2) ** 2 / (2 * (M1 + M2))
    assert row["ke_loss_J"] == pytest.approx(expected, rel=1e-9)
    assert row["ke_loss_predicted_J"] == pytest.approx(row["ke_loss_J"], rel=1e-9)
    assert row["v1n_after_e_mps"] == pytest.approx(row["v1n_after_mps"], abs=1e-9)
    assert row["v2n_after_e_mps"] == pytest.approx(row["v2n_after_mps"], abs=1e-9)
    np.testing.assert_allclose([row["nx"], row["ny"], row["nz"]], [1, 0, 0], atol=1e-12)


def test_analytic_limits():
    """The handout's elastic answer for 1 kg at 3 m/s against 2 kg at -1 m/s."""
    v1, v2 = collision_after(1.0, 2.0, 3.0, -1.0, 1.0)
    assert (v1, v2) == (pytest.approx(-7 / 3), pytest.approx(5 / 3))
    w1, w2 = collision_after(1.0, 2.0, 3.0, -1.0, 0.0)
    assert w1 == pytest.approx(w2) == pytest.approx(1 / 3)


def test_no_collision_gives_a_row_with_the_reason(record_spec):
    """Stopped before the balls meet (the handout's Step 3 as written): a row, no e, a reason."""
    (path,) = record_spec("known_collision_miss", COLLISION_SPEC, overrides=["stop.max_time=0.05"])
    a = analyze_run(load_log(path))
    assert a.collisions.height == 1
    row = a.collisions.row(0, named=True)
    assert not row["complete"] and row["e_velocity"] is None
    assert "never happened" in row["note"]
    assert row["v1x_after_mps"] == pytest.approx(V1)  # "after" equals "before"
    assert a.summary["note"]


@pytest.mark.slow  # records a calibrated drop and collision per integrator: about 3 s each
@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_calibrated_impacts_carry_their_target_in_its_range(record_spec, integrator):
    """A drop's first impact, at the top of the range its contact was designed for (measured
    within a step of gravity of it, either way), and a calibrated collision carry the pair's
    target e; the known collision, not calibrated, none."""
    from specs import collision, drop, toml

    (path,) = record_spec(
        f"target_drop_{integrator}",
        toml(
            drop(
                "target_drop",
                z=0.6,
                timestep=1e-5,
                integrator=integrator,
                contact={"restitution": 0.8},
                bounces=2,
                max_time=2.0,
            )
        ),
    )
    bounces = analyze_run(load_log(path)).bounces
    assert bounces["target_e"].to_list() == [0.8, 0.8]
    (path,) = record_spec(
        f"target_collision_{integrator}",
        toml(collision("target_collision", timestep=1e-5, contact={"restitution": 0.7})),
    )
    assert analyze_run(load_log(path)).collisions["target_e"].to_list() == [0.7]


def test_a_collision_without_a_calibrated_pair_has_no_target(hit):
    assert hit.collisions["target_e"].to_list() == [None]
