"""The designer over a speed range and per integrator, checked against MuJoCo itself.

Accuracy from recorded logs, bounce by bounce, is in tests/calibrate/test_calibrate.py (the multi-bounce
case); this module checks the pieces: the step emulations against `mj_step` for every
integrator, the fast evaluation against the emulation, the predicted worst case over a range
against single impacts measured in plain MuJoCo, the timestep advice, and the errors.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import plain_mujoco as measure
import pytest

from impactlab import contact as C
from impactlab.contact import calibration, design, emulation, fast, table

TOL = C.RESTITUTION_TOLERANCE
LADDER = (5e-5, 2e-5, 1e-5, 5e-6, 2e-6, 1e-6)


def _design(e, r, speeds, integrator="Euler", g=9.81) -> C.ContactParams:
    """The design at the coarsest timestep of a ladder that resolves it."""
    for dt in LADDER:
        try:
            return C.contact_params(
                e,
                radius_m=r,
                speed_range_mps=speeds,
                timestep_s=dt,
                integrator=integrator,
                gravity_mps2=g,
            )
        except C.ContactModelError as exc:
            if "timestep" not in str(exc):
                raise
    raise AssertionError(f"no timestep for e={e}, r={r}, {speeds}")


def _trajectory(xml: str, integrator: str, steps: int, v: float) -> np.ndarray:
    model = mujoco.MjModel.from_xml_string(
        xml.replace('integrator="Euler"', f'integrator="{integrator}"')
    )
    data = mujoco.MjData(model)
    data.qpos[2] = 0.05 + 0.63 * v * model.opt.timestep
    data.qvel[2] = -v
    out = np.empty((steps, 2))
    for i in range(steps):
        mujoco.mj_step(model, data)
        out[i] = data.qpos[2], data.qvel[2]
    return out


def test_rk4_emulation_matches_mj_step():
    """The RK4 step emulation (four stages, the constraint evaluated at each) is MuJoCo's."""
    p = _design(0.5, 0.05, (1.0, 3.0), "RK4")
    w0, v, dt, g = math.sqrt(p.stiffness), 2.0, p.timestep_s, 9.81
    traj = _trajectory(
        measure.ball_plane_mjcf(p, radius_m=0.05, mass_kg=3.0, gravity_mps2=g), "RK4", 400, v
    )
    y = np.array([0.63 * v * dt * w0 / v])
    u = np.array([-1.0])
    for i in range(400):
        y, u, _ = emulation.step(y, u, w0 * dt, 2.0 * p.zeta, g / (w0 * v), "rk4")
        assert (traj[i, 0] - 0.05) * w0 / v == pytest.approx(y[0], abs=1e-12)
        assert traj[i, 1] / v == pytest.approx(u[0], abs=1e-12)
    assert traj[-1, 1] > 0.0  # it bounced


@pytest.mark.slow
@pytest.mark.parametrize("integrator", ["implicit", "implicitfast"])
def test_implicit_integrators_step_this_contact_as_euler(integrator):
    """A free ball has no velocity-dependent passive or actuator force: MuJoCo's implicit
    integrators give Euler's trajectory, so Euler's emulation and table apply to them."""
    p = _design(0.3, 0.05, (0.5, 3.0))
    xml = measure.ball_plane_mjcf(p, radius_m=0.05, mass_kg=0.7, gravity_mps2=9.81)
    n = int(3 * p.duration_s / p.timestep_s)
    euler, other = _trajectory(xml, "Euler", n, 2.0), _trajectory(xml, integrator, n, 2.0)
    assert np.abs(other - euler).max() <= 1e-12
    assert euler[-1, 1] > 0.0
    assert C.INTEGRATORS == ("Euler", "implicit", "implicitfast", "RK4")


@pytest.mark.slow
@pytest.mark.parametrize("integrator", ["Euler", "RK4"])
def test_fast_evaluation_is_the_emulation(integrator):
    """The closed-form force phase gives the stepped emulation's numbers, grip and all."""
    phases = np.linspace(0.01, 1.0, 23)
    for zeta in (0.003, 0.07, 0.45, 0.9):
        for h in (0.01, 0.04, 0.2):
            for gr in (0.0, 0.003, 0.05, 0.6):
                r1, s1, _ = emulation.emulate_surface(zeta, h, phases, gr, integrator=integrator)
                r2, s2 = fast.impact_fast(
                    zeta, h, phases, np.full(phases.size, gr), integrator=integrator
                )
                np.testing.assert_allclose(s2, s1, atol=1e-12)
                np.testing.assert_allclose(r2, r1, atol=1e-12)


RANGE_CASES = [
    (0.2, 0.1, (1.0, 3.0), "Euler"),
    (0.35, 0.3, (0.5, 2.0), "Euler"),
    (0.5, 0.03, (0.5, 8.0), "Euler"),
    (0.8, 0.05, (0.5, 6.0), "RK4"),
    (0.9, 0.2, (0.5, 10.0), "implicitfast"),
    (0.99, 0.1, (1.0, 10.0), "Euler"),
    (0.6, 0.1, (2.0, 2.0), "RK4"),
]


@pytest.mark.slow
@pytest.mark.parametrize(("e", "r", "speeds", "integrator"), RANGE_CASES)
def test_range_design_predicted_within_tolerance(e, r, speeds, integrator):
    """Over the range, every impact (64 step phases at 7 speeds, the step emulation) is
    within the tolerance, gravity's shift centred across it; below it e drifts down."""
    p = _design(e, r, speeds, integrator)
    assert p.speed_range_mps == speeds and p.integrator == integrator
    assert p.predicted_error <= 0.004 + 1e-6
    assert p.gravity_spread <= C.SPREAD_BUDGET * 1.05
    pred = C.predict(p)
    assert pred.worst_error(e) <= TOL
    inside = [m for m, ok in zip(pred.mean, pred.in_range, strict=True) if ok]
    # gravity's shift centred across the range: the ends' mean over step phases straddle the
    # target (up to the difference between the phase mean and the calibrated phase midrange)
    assert abs(0.5 * (inside[0] + inside[-1]) - e) <= 0.002
    if p.gravity_spread > 5e-4:
        assert inside[0] < e < inside[-1]
    below = [m for m, ok in zip(pred.mean, pred.in_range, strict=True) if not ok]
    assert len(below) == 2
    if p.gravity_spread > 5e-4:  # gravity matters: below the range e keeps falling
        assert below[1] < inside[0]
    assert p.max_penetration_m <= 0.02 * r


@pytest.mark.slow
@pytest.mark.parametrize(
    ("e", "r", "speeds", "integrator"),
    [(0.3, 0.1, (0.5, 3.0), "Euler"), (0.7, 0.2, (0.5, 4.0), "RK4"), (0.9, 0.03, (1.0, 6.0), "implicit")],
)  # fmt: skip
def test_range_design_measured_in_mujoco(e, r, speeds, integrator):
    """Single impacts in plain MuJoCo at both ends and the middle of the range, two onset
    phases each: within the tolerance, penetration within the bound."""
    p = _design(e, r, speeds, integrator)
    for v in (speeds[0], math.sqrt(speeds[0] * speeds[1]), speeds[1]):
        for gap_steps in (2.13, 2.71):
            meas = measure.measure_ball_plane(
                p, radius_m=r, mass_kg=1.3, impact_speed_mps=v, gap_m=gap_steps * v * p.timestep_s
            )
            assert abs(meas.restitution - e) <= TOL, (v, meas)
            assert meas.max_penetration_m <= 0.02 * r


def test_coarse_timestep_names_the_largest_that_works_and_advises():
    kw = dict(radius_m=0.05, speed_range_mps=(0.5, 6.0), gravity_mps2=9.81)
    with pytest.raises(C.ContactModelError, match=r"over 0\.5\.\.6 m/s.*timestep <= ") as info:
        C.contact_params(0.8, timestep_s=3e-5, **kw)
    dt_max = float(info.value.args[0].split("timestep <= ")[1].split(" s")[0])
    assert 5e-6 < dt_max < 3e-5
    assert C.contact_params(0.8, timestep_s=0.98 * dt_max, **kw).predicted_error <= 0.004
    design = C.design_contact(0.8, timestep_s=3e-5, **kw)
    assert not design.ok and design.timestep_max_s == pytest.approx(dt_max, rel=0.02)
    assert design.best is not None and design.best_prediction is not None
    assert design.best_prediction.worst_error(0.8) <= TOL  # achievable, softer
    assert design.best.max_penetration_m > 0.02 * 0.05
    # the softer contact it suggests meets the target at the coarse timestep when asked for
    assert design.softer is not None
    from impactlab.contact.summary import round_up

    pen = round_up(design.softer.max_penetration_m)
    p = C.contact_params(0.8, timestep_s=3e-5, max_penetration_m=pen, **kw)
    assert C.predict(p).worst_error(0.8) <= TOL


def test_a_fixed_duration_that_gravity_spreads_too_much_is_refused():
    with pytest.raises(C.ContactModelError, match="gravity changes e by"):
        C.contact_params(
            0.3, radius_m=0.1, speed_range_mps=(0.2, 5.0), timestep_s=1e-5, duration_s=0.01
        )


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"speed_range_mps": (3.0, 1.0)}, "v_lo <= v_hi"),
        ({"speed_range_mps": (0.0, 1.0)}, "positive"),
        ({"speed_range_mps": ("a", 1.0)}, "positive"),
        ({"speed_range_mps": (1.0,)}, "two speeds"),
        ({"speed_range_mps": (1.0, 2.0), "impact_speed_mps": 1.0}, "or impact_speed_mps"),
        ({}, "or impact_speed_mps"),
        ({"speed_range_mps": (1.0, 2.0), "integrator": "Verlet"}, "Euler, implicit"),
    ],
)
def test_bad_ranges_and_integrators_raise(kwargs, words):
    with pytest.raises(C.ContactModelError, match=words):
        C.contact_params(0.5, radius_m=0.1, timestep_s=1e-5, **kwargs)


def test_contact_params_over_a_range_converges_in_a_few_evaluations_without_simulating(
    monkeypatch, count_calls
):
    """No simulation, and a handful of closed-form evaluations: the stiffness iteration
    converges well before its cap (16), gravity's shift takes a few step-emulation
    evaluations each. Counted, not timed (the speed is `benchmarks/bench.py`'s business)."""

    def forbidden(*args: object, **kwargs: object) -> None:
        raise AssertionError("contact_params must not simulate")

    monkeypatch.setattr(mujoco, "mj_step", forbidden)
    monkeypatch.setattr(table, "emulate_surface", forbidden)
    monkeypatch.setattr(fast, "emulate_surface", forbidden)  # no column falls back to stepping
    calls = count_calls((calibration, "evaluate"), (design, "evaluate"), (fast, "impact_fast"))
    for i in range(12):
        calls.clear()
        C.contact_params(
            0.25 + 0.06 * i,
            radius_m=0.1,
            speed_range_mps=(0.5, 5.0),
            timestep_s=1e-6,
            integrator=("Euler", "RK4")[i % 2],
        )
        # measured: 3 to 5 evaluations, 6 to 11 emulation evaluations per call
        assert 1 <= calls["evaluate"] <= 8, calls
        assert calls["impact_fast"] <= 24, calls
