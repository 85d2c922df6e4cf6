"""Energy bookkeeping: rotational energy in the body frame, flight drift, contact losses."""

from __future__ import annotations

import math

import numpy as np
import polars as pl
import pytest
from known import DROP_SPEC, DT, RADIUS, Z0, G

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.analyze.measure.energy import CONSTANTS, constants, energy_rows
from impactlab.analyze.measure.phases import WORK_COLUMNS
from impactlab.logs.load import BodyInfo, load_log


def _state(**kw) -> pl.DataFrame:
    row = dict.fromkeys(("x", "y", "z", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz"), 0.0)
    row |= {"run_id": "r", "t_ns": 0, "t_s": 0.0, "qw": 1.0} | kw
    return pl.DataFrame([row])


def test_rotational_energy_uses_body_frame():
    """Body turned 90 deg about z: world omega along x is body omega along -y.

    With principal inertia (1, 2, 3) kg m^2 and |omega| = 2 rad/s, KE_rot = 0.5 * 2 * 4 = 4 J
    (it would be 2 J with the world-frame omega). Potential: 1 kg, 0.5 m above the reference.
    """
    s = math.sqrt(0.5)
    state = _state(qw=s, qz=s, wx=2.0, z=1.5)
    info = BodyInfo("b", 1.0, (1.0, 2.0, 3.0), 0.1)
    values = constants(info, np.array([0, 0, -G]), np.array([0, 0, 1.0]))
    e = energy_rows(
        state.with_columns(body=pl.lit("b"), **dict(zip(CONSTANTS, values, strict=True)))
    )
    assert e["ke_rot_J"][0] == pytest.approx(4.0, rel=1e-12)
    assert e["pe_J"][0] == pytest.approx(0.5 * G, rel=1e-12)
    assert e["height_m"][0] == pytest.approx(0.5, rel=1e-12)


@pytest.fixture(scope="module")
def drop(record_spec):
    (path,) = record_spec("known_drop", DROP_SPEC)
    return analyze_run(load_log(path))


@pytest.mark.slow
def test_resting_reference_and_initial_energy(drop):
    """Potential energy is zero at the contact height: E(0) = m g (z0 - r) + m v0^2 / 2."""
    total = drop.energy.filter(pl.col("body") == "total").sort("t_ns")
    v0sq = 0.3**2 + 0.5**2
    assert total["total_J"][0] == pytest.approx(G * (Z0 - RADIUS) + v0sq / 2, rel=1e-12)


def test_flight_drift_is_the_euler_drift(drop):
    """In each flight no force but gravity works: the budget's residual is the semi-implicit
    drift, exactly m g^2 dt / 2 per step, rtol 1e-6.

    Bound relative to the drop energy: |drift| / E(0) <= g dt T / (2 h0) < 5e-4 here (T <= 0.7 s).
    """
    flights = drop.phases.filter(pl.col("kind") == "flight")
    assert flights.height >= 3
    expected = -1.0 * G**2 * DT * (flights["end_t_s"] - flights["start_t_s"]) / 2
    np.testing.assert_allclose(flights["residual_J"], expected, rtol=1e-6, atol=1e-12)
    assert (flights.select(pl.sum_horizontal(WORK_COLUMNS).abs()).to_series() == 0).all()
    energy_start = drop.summary["energy_initial_J"]
    assert drop.summary["flight_drift_max_rel"] < 5e-4
    assert (flights["residual_J"].abs() / energy_start < 5e-4).all()


def test_the_budget_closes_and_books_each_bounce_to_the_contact(drop):
    """E(end) - E(0) = the works of every phase plus their residuals (to 1e-9 J); each
    contact's work is the kinetic energy it took along the normal, m (v_in^2 - v_out^2) / 2
    (1 %: gravity works during the contact too); its residual is the semi-implicit
    integrator's, g dt / 2 per unit of impulse (m = 1 kg): at most g dt |v_out - v_in|."""
    total = drop.energy.filter(pl.col("body") == "total").sort("t_ns")
    phases = drop.phases
    works = phases.select(pl.sum_horizontal(WORK_COLUMNS)).to_series()
    assert total["total_J"][-1] - total["total_J"][0] == pytest.approx(
        works.sum() + phases["residual_J"].sum(), abs=1e-9
    )
    b = drop.bounces.filter(pl.col("complete"))
    c = phases.filter(pl.col("kind") == "contact").head(b.height)
    taken = -(c["work_contact_normal_J"] + c["work_contact_friction_J"])
    np.testing.assert_allclose(taken, 0.5 * (b["v_in_mps"] ** 2 - b["v_out_mps"] ** 2), rtol=0.01)
    impulse = b["v_out_mps"] - b["v_in_mps"]
    assert (c["residual_J"].abs() <= G * DT * impulse).all()


def test_mujoco_energy_agrees_after_shift(drop):
    """MuJoCo's own energy channel, its potential (m g z of the centre) shifted by m g r,
    matches the energy computed from the logged states at every step (1e-9 J)."""
    assert drop.summary["mujoco_diff_max_J"] < 1e-9
