"""Known-answer tests of the bounce analysis on a run recorded with a known contact.

The contact is MuJoCo's direct form, solref = (-k, -b) with k = 1e5 1/s^2 and b = 2 zeta sqrt(k),
zeta = 0.1, with constant impedance 0.9999: a linear spring-dashpot whose restitution is the
Schwager-Poeschel closed form (docs: physics notes), e = 0.7441 at zeta = 0.1.
"""

from __future__ import annotations

import math

import numpy as np
import polars as pl
import pytest
from known import DROP_SPEC, DT, VX0, VZ0, Z0, ZETA, G, K, schwager_poeschel

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.logs.load import load_log


@pytest.fixture(scope="module")
def drop(record_spec):
    (path,) = record_spec("known_drop", DROP_SPEC)
    return analyze_run(load_log(path))


def test_closed_form_value():
    assert schwager_poeschel(0.1) == pytest.approx(0.7441, abs=5e-5)


@pytest.mark.slow
def test_free_flight_matches_parabola(drop):
    """Before the first contact z(t) = z0 + v0 t - g t^2 / 2, up to semi-implicit Euler.

    MuJoCo's Euler updates v then x, so z_n = z0 + v0 t + ... - g t^2/2 - g dt t / 2 exactly:
    the tolerance is that term, g dt t / 2 (<= 0.3 mm here), plus 1e-9 m of rounding.
    """
    first = drop.bounces["impact_t_s"][0]
    ball = drop.states.filter((pl.col("body") == "ball") & (pl.col("t_s") < first))
    t = ball["t_s"].to_numpy()
    exact = Z0 + VZ0 * t - G * t**2 / 2
    err = ball["z"].to_numpy() - exact
    assert np.all(np.abs(err) <= G * DT * t / 2 + 1e-9)
    np.testing.assert_allclose(err, -G * DT * t / 2, atol=1e-9)  # the Euler term, no more
    np.testing.assert_allclose(ball["x"].to_numpy(), VX0 * t, atol=1e-12)


def test_restitution_recovered_from_known_contact(drop):
    """e from velocities within 0.01 of the closed form; apexes give the same e (0.003)."""
    b = drop.bounces.filter(pl.col("complete"))
    assert b.height >= 2
    e_sp = schwager_poeschel(ZETA)
    assert abs(b["e_velocity"][0] - e_sp) < 0.01
    for e in b["e_velocity"]:
        assert abs(e - e_sp) < 0.01
    apex = b.filter(pl.col("e_apex").is_not_null())
    assert apex.height >= 2
    np.testing.assert_allclose(apex["e_apex"], apex["e_velocity"], atol=0.003)


def test_drop_height_and_impact_speed(drop):
    """h(0) = 1 m + v0z^2 / (2 g) above the contact height; v_in^2 = 2 g h(0) to 0.1 %."""
    first = drop.bounces.row(0, named=True)
    h0 = 1.0 + VZ0**2 / (2 * G)
    assert first["apex_before_m"] == pytest.approx(h0, abs=VZ0 * DT)
    assert first["v_in_mps"] == pytest.approx(-math.sqrt(2 * G * h0), rel=1e-3)


def test_apex_predicted_from_release_velocity(drop):
    """Measured apex = h_release + v_out^2 / (2 g) within 2 v_out dt (the step's resolution)."""
    b = drop.bounces.filter(pl.col("apex_m").is_not_null())
    assert b.height >= 2
    tol = 2 * b["v_out_mps"] * DT + 1e-9
    assert ((b["apex_m"] - b["apex_predicted_m"]).abs() <= tol).all()


def test_contact_quantities(drop):
    """Contact duration of the linear dashpot, impulse = m (v_out - v_in), positive force."""
    b = drop.bounces.filter(pl.col("complete"))
    w = math.sqrt(K) * math.sqrt(1 - ZETA**2)
    # the force reaches zero before the half period pi / w (Schwager-Poeschel); 5 % and 2 steps
    assert ((b["duration_s"] < math.pi / w + 2 * DT) & (b["duration_s"] > 0.8 * math.pi / w)).all()
    # impulse of the normal force minus gravity over the contact ~ momentum change
    dp = b["v_out_mps"] - b["v_in_mps"]
    np.testing.assert_allclose(b["impulse_Ns"] - G * b["duration_s"], dp, rtol=0.02)
    assert (b["peak_force_N"] > 0).all() and (b["max_penetration_m"] > 0).all()


def test_last_bounce_left_open_is_not_used(record_spec):
    """A log cut during a contact marks that bounce incomplete, without e."""
    (path,) = record_spec("known_drop_cut", DROP_SPEC, overrides=["stop.max_time=0.508"])
    a = analyze_run(load_log(path))
    last = a.bounces.row(-1, named=True)
    assert not last["complete"]
    assert last["e_velocity"] is None
    assert "still in contact" in last["note"]
