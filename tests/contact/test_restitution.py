"""Tests of the restitution -> MuJoCo contact-parameter translation (measured in MuJoCo)."""

from __future__ import annotations

import itertools
import json
import math

import mujoco
import numpy as np
import plain_mujoco as measure
import pytest

from impactlab import contact as R
from impactlab.contact import calibration, design, emulation, fast, table

# Schwager-Poeschel column of the table in shared/notes/physics.md
NOTES_TABLE = {0.02: 0.9398, 0.10: 0.7441, 0.30: 0.4510, 0.50: 0.2984, 0.80: 0.1798}
TOL = R.RESTITUTION_TOLERANCE


def _params(e: float, v: float, *, gravity: float, radius: float = 0.1) -> R.ContactParams:
    """Calibrated parameters at the coarsest of a few timesteps the check accepts."""
    for dt in (2e-5, 1e-5, 5e-6, 2.5e-6):
        try:
            return R.contact_params(
                e, radius_m=radius, impact_speed_mps=v, timestep_s=dt, gravity_mps2=gravity
            )
        except R.ContactModelError:
            continue
    raise AssertionError(f"no timestep accepted for e={e}, v={v}")


@pytest.mark.parametrize(("zeta", "expected"), NOTES_TABLE.items())
def test_closed_form_matches_notes_and_inverts(zeta: float, expected: float) -> None:
    assert R.restitution_closed_form(zeta) == pytest.approx(expected, abs=1e-3)
    assert R.zeta_for_restitution(R.restitution_closed_form(zeta)) == pytest.approx(zeta, abs=1e-9)


def test_closed_form_limits_and_floor() -> None:
    assert R.restitution_closed_form(0.0) == 1.0
    assert R.restitution_closed_form(1.0) == pytest.approx(math.exp(-2.0))
    # continuous across the two underdamped branches and across critical damping
    for z in (math.sqrt(0.5), 1.0):
        assert R.restitution_closed_form(z - 1e-9) == pytest.approx(
            R.restitution_closed_form(z + 1e-9), abs=1e-6
        )
    zs = np.linspace(0.0, 1.0, 201)
    es = np.array([R.restitution_closed_form(z) for z in zs])
    assert np.all(np.diff(es) < 0.0)  # monotone: the floor is the value at critical damping
    assert es.min() == pytest.approx(R.RESTITUTION_FLOOR, abs=1e-12)
    # the zero-gravity max penetration factor agrees with a fine integration
    for z in (0.05, 0.5, 0.9):
        h, y, u, ymax = 1e-5, 0.0, 1.0, 0.0
        while u > 0.0:
            u += h * (-y - 2.0 * z * u)
            y += h * u
            ymax = max(ymax, y)
        assert R.max_penetration_factor(z) == pytest.approx(ymax, rel=1e-4)


@pytest.mark.parametrize("bad", [0.1, R.RESTITUTION_FLOOR - 1e-3, 1.01, float("nan"), "x"])
def test_unreachable_targets_raise_with_floor(bad: object) -> None:
    with pytest.raises(R.ContactModelError, match=r"0\.1353"):
        R.contact_params(bad, radius_m=0.1, impact_speed_mps=1.0, timestep_s=1e-5)  # type: ignore[arg-type]
    assert issubclass(R.ContactModelError, ValueError)


@pytest.mark.slow
@pytest.mark.parametrize("scheme", sorted(table.TABLE_PATHS))
def test_table_is_up_to_date(scheme: str) -> None:
    """The committed table is what `python -m impactlab.contact.table` writes, within a
    tolerance: numpy's vectorised kernels round the last bit differently on different CPUs
    (e.g. with and without AVX-512), and the tables store 10 decimals, so a value on a
    rounding boundary may move by one unit of 1e-10. Far below what matters: the accuracy
    promised for e is 5e-3."""
    committed = json.loads(table.TABLE_PATHS[scheme].read_text())
    fresh = table.generate_table(scheme)
    assert set(committed) == set(fresh)
    for key, value in fresh.items():
        if isinstance(value, list):
            np.testing.assert_allclose(committed[key], value, rtol=1e-12, atol=2e-10, err_msg=key)
        else:
            assert committed[key] == value, key


@pytest.mark.parametrize(
    ("e", "v", "phase"), [(0.2, 1.0, 0.37), (0.5, 2.0, 0.81), (0.9, 1.0, 0.05)]
)
def test_surface_emulation_matches_mj_step(e: float, v: float, phase: float) -> None:
    """The numpy emulation the tables and the designer use reproduces MuJoCo step by step:
    the velocity when the force lets go, and in the first state back at the surface."""
    p = R.contact_params(e, radius_m=0.05, impact_speed_mps=v, timestep_s=2e-5)
    w0, dt, g = math.sqrt(p.stiffness), p.timestep_s, 9.81
    model = mujoco.MjModel.from_xml_string(
        measure.ball_plane_mjcf(p, radius_m=0.05, mass_kg=3.0, gravity_mps2=g)
    )
    data = mujoco.MjData(model)
    # the last state before the overlap: speed v, (1 - phase) steps of travel above the plane
    data.qpos[2] = 0.05 + (1.0 - phase) * (v + g * dt) * dt
    data.qvel[2] = -v
    pushed, let_go = False, None
    while not pushed or data.qpos[2] < 0.05:
        u = float(data.qvel[2])
        mujoco.mj_step(model, data)
        force = bool(np.any(data.efc_force[: data.nefc] > 0.0))
        if pushed and not force and let_go is None:
            let_go = u  # the velocity of the first state whose step has no force
        pushed |= force
    release, surface, _ = emulation.emulate_surface(
        p.zeta, w0 * dt, np.array([phase]), g / (w0 * v)
    )
    assert let_go is not None and let_go / v == pytest.approx(release[0], abs=1e-12)
    assert data.qvel[2] / v == pytest.approx(surface[0], abs=1e-12)
    assert release[0] > surface[0] + 0.5 * p.zeta * g / (w0 * v)  # gravity after the release
    # the closed-form evaluation used by contact_params gives the same numbers
    phases = np.linspace(0.01, 1.0, 37)
    for gr in (0.0, g / (w0 * v), 0.3):
        r1, s1, _ = emulation.emulate_surface(p.zeta, w0 * dt, phases, gr)
        r2, s2 = fast.impact_fast(p.zeta, w0 * dt, phases, np.full(phases.size, gr))
        np.testing.assert_allclose(r2, r1, atol=1e-12)
        np.testing.assert_allclose(s2, s1, atol=1e-12)


GRID = list(itertools.product([0.2, 0.5, 0.9, 0.99], [1.0, 3.0, 10.0], [0.1, 10.0]))


@pytest.mark.parametrize(("e", "v", "m"), GRID)
def test_grid_ball_plane_with_gravity(e: float, v: float, m: float) -> None:
    """Surface to surface, as the analysis stage measures (gravity's shift calibrated out)."""
    p = _params(e, v, gravity=9.81)
    for gap_steps in (2.13, 2.71):  # two different contact-onset phases
        meas = measure.measure_ball_plane(
            p, radius_m=0.1, mass_kg=m, impact_speed_mps=v, gap_m=gap_steps * v * p.timestep_s
        )
        assert abs(meas.restitution - e) <= TOL, (meas, p)
        assert meas.max_penetration_m <= 0.02 * 0.1
        assert meas.max_penetration_m <= p.max_penetration_m * 1.01


@pytest.mark.parametrize(("e", "v", "m"), GRID)
def test_grid_ball_ball_zero_gravity(e: float, v: float, m: float) -> None:
    p = _params(e, v, gravity=0.0, radius=0.05)
    meas = measure.measure_ball_ball(
        p, radius_m=(0.05, 0.2), mass_kg=(m, 1.0), velocity_mps=(v, 0.0)
    )
    assert abs(meas.restitution - e) <= TOL, (meas, p)
    assert meas.max_penetration_m <= 0.02 * 0.05


def test_collision_velocities_and_momentum() -> None:
    m1, m2, v1, v2, e = 0.5, 1.0, 2.0, -1.0, 0.7
    p = R.contact_params(e, radius_m=0.1, impact_speed_mps=v1 - v2, timestep_s=1e-5, gravity_mps2=0)
    meas = measure.measure_ball_ball(
        p, radius_m=(0.1, 0.1), mass_kg=(m1, m2), velocity_mps=(v1, v2)
    )
    v1p = (m1 * v1 + m2 * v2 + m2 * e * (v2 - v1)) / (m1 + m2)
    v2p = (m1 * v1 + m2 * v2 + m1 * e * (v1 - v2)) / (m1 + m2)
    assert meas.v_after_mps[0] == pytest.approx(v1p, rel=5e-3)
    assert meas.v_after_mps[1] == pytest.approx(v2p, rel=5e-3)
    p_in = m1 * meas.v_before_mps[0] + m2 * meas.v_before_mps[1]
    p_out = m1 * meas.v_after_mps[0] + m2 * meas.v_after_mps[1]
    assert abs(p_out - p_in) <= 1e-9 * (m1 * abs(v1) + m2 * abs(v2))


def test_low_speed_gravity_dependence() -> None:
    """A contact designed at 1 m/s without gravity, hit under gravity: at 0.1 and 0.3 m/s
    gravity lowers e, by as much as the step emulation predicts."""
    e = 0.5
    p = R.contact_params(e, radius_m=0.2, impact_speed_mps=1.0, timestep_s=2e-5, gravity_mps2=0)
    assert p.gravity_shift == 0.0
    speeds = [0.1, 0.3, 1.0]
    predicted, _, _ = R.restitution_spread(
        p, impact_speed_mps=speeds, gravity_mps2=9.81, timestep_s=p.timestep_s
    )
    for v, min_shift, pred in zip(speeds, (0.05, 0.05, 0.02), predicted, strict=True):
        meas = measure.measure_ball_plane(p, radius_m=0.2, mass_kg=1.0, impact_speed_mps=v)
        assert meas.restitution == pytest.approx(pred, abs=0.002)
        assert e - meas.restitution > min_shift
    weightless, _, _ = R.restitution_spread(
        p, impact_speed_mps=1.0, gravity_mps2=0.0, timestep_s=p.timestep_s
    )
    assert weightless[0] == pytest.approx(e, abs=0.002)


def test_gravity_is_calibrated_at_the_design_speed() -> None:
    """Designed with gravity: the target at the design speed, lower below it, higher above it
    (by at most the shift that was calibrated out); the release velocity is higher."""
    e, v, g, dt = 0.2, 1.0, 9.81, 2e-5
    # stiff enough for g / (w0 v) = 0.015, where the shift is close to its first order
    p = R.contact_params(
        e, radius_m=0.1, impact_speed_mps=v, timestep_s=dt, gravity_mps2=g, max_penetration_m=8e-4
    )
    w0 = math.sqrt(p.stiffness)
    assert g / (w0 * v) == pytest.approx(0.015, rel=0.1)
    assert p.gravity_mps2 == g
    assert p.gravity_shift == pytest.approx(-2.0 * p.zeta * g / (w0 * v), rel=0.1)
    assert p.gravity_shift < -0.015  # three times the tolerance: calibrated out
    speeds = [0.3, 1.0, 3.0, 10.0]
    surface, _, _ = R.restitution_spread(p, impact_speed_mps=speeds, gravity_mps2=g, timestep_s=dt)
    assert surface[1] == pytest.approx(e, abs=0.001)
    assert surface[0] < e - 0.02
    assert np.all(np.diff(surface) > 0.0)
    assert surface[-1] < e - p.gravity_shift
    phases = (np.arange(64) + 0.5) / 64
    release, _, _ = emulation.emulate_surface(p.zeta, w0 * dt, phases, g / (w0 * v))
    released = float(release.mean()) / float(emulation.speed_in(w0 * dt, g / (w0 * v), "euler"))
    assert released - surface[1] == pytest.approx(-p.gravity_shift, abs=0.002)
    meas = measure.measure_ball_plane(p, radius_m=0.1, mass_kg=1.0, impact_speed_mps=v)
    assert meas.restitution == pytest.approx(e, abs=TOL)
    # without gravity the same contact is not shifted (ball-ball parameters: no correction)
    q = R.contact_params(e, radius_m=0.1, impact_speed_mps=v, timestep_s=dt, gravity_mps2=0)
    assert q.gravity_shift == 0.0 and q.zeta > p.zeta


def test_coarse_timestep_raises_with_numbers_and_opt_out_warns() -> None:
    with pytest.raises(R.ContactModelError, match=r"steps per contact.*timestep <= ") as info:
        R.contact_params(0.5, radius_m=0.1, impact_speed_mps=10.0, timestep_s=1e-4)
    dt_max = float(info.value.args[0].split("timestep <= ")[1].split(" s")[0])
    p = R.contact_params(0.5, radius_m=0.1, impact_speed_mps=10.0, timestep_s=0.98 * dt_max)
    assert p.steps_per_contact >= 50
    with pytest.warns(UserWarning, match="steps per contact"):
        R.contact_params(
            0.5, radius_m=0.1, impact_speed_mps=10.0, timestep_s=1e-4, allow_coarse=True
        )


def test_explicit_duration_and_penetration() -> None:
    p = R.contact_params(0.8, radius_m=0.1, impact_speed_mps=2.0, timestep_s=1e-5, duration_s=2e-3)
    assert p.duration_s == pytest.approx(2e-3, rel=1e-6)
    q = R.contact_params(
        0.8, radius_m=0.1, impact_speed_mps=2.0, timestep_s=1e-5, max_penetration_m=1e-3
    )
    assert q.max_penetration_m <= 1e-3
    meas = measure.measure_ball_plane(q, radius_m=0.1, mass_kg=1.0, impact_speed_mps=2.0)
    assert meas.max_penetration_m <= 1e-3
    assert abs(meas.restitution - 0.8) <= TOL
    with pytest.raises(R.ContactModelError, match="not both"):
        R.contact_params(
            0.8, radius_m=0.1, impact_speed_mps=2.0, timestep_s=1e-5,
            duration_s=1e-3, max_penetration_m=1e-3,
        )  # fmt: skip


def test_contact_params_converges_in_a_few_evaluations_without_simulating(
    monkeypatch: pytest.MonkeyPatch, count_calls
) -> None:
    """No simulation, a handful of closed-form evaluations per design (counted, not timed)."""

    def forbidden(*args: object) -> None:
        raise AssertionError("contact_params must not simulate")

    monkeypatch.setattr(mujoco, "mj_step", forbidden)
    monkeypatch.setattr(table, "emulate_surface", forbidden)  # the closed form is used instead
    monkeypatch.setattr(fast, "emulate_surface", forbidden)  # no column falls back to stepping
    calls = count_calls((calibration, "evaluate"), (design, "evaluate"), (fast, "impact_fast"))
    for i in range(20):
        calls.clear()
        R.contact_params(0.2 + 0.04 * i, radius_m=0.1, impact_speed_mps=1.0, timestep_s=1e-5)
        # measured: 3 to 6 evaluations, 6 to 34 emulation evaluations per call; the stiffness
        # iteration's cap is 16
        assert 1 <= calls["evaluate"] <= 8, calls
        assert calls["impact_fast"] <= 60, calls
