"""A target e(v): the impedance emulation against mj_step, and designed contacts run in plain
MuJoCo (an MJCF string with the designed solref/solimp, `mj_step`, e from the ball's
velocities at contact onset and release), at and between the curve's points."""

from __future__ import annotations

import math
import warnings

import mujoco
import numpy as np
import plain_mujoco as measure
import pytest

from impactlab import contact as C
from impactlab.contact import emulation, shaped
from impactlab.contact.curve import ramirez_curve

DT, R, G = 1e-5, 0.033, 9.81
TARGETS = {
    "ramirez": ramirez_curve(0.25, 0.0375, (0.5, 10.0)),
    "table": C.RestitutionCurve.of([0.5, 1, 2, 4, 8, 10], [0.86, 0.85, 0.82, 0.78, 0.72, 0.70]),
    "constant": C.RestitutionCurve.of([0.5, 10.0], [0.8, 0.8]),
}
SHAPES = [
    (0.0005, 0.9999, 0.002, 0.5, 12.0),
    (0.01, 0.95, 0.003, 0.3, 3.0),
    (0.2, 0.9, 0.001, 0.8, 1.0),
    (0.9, 0.2, 0.002, 0.5, 2.0),
]


def _shaped(solimp, k=9e6, b=600.0) -> C.ContactParams:
    """A contact with a rising impedance, by hand (no fit)."""
    return C.ContactParams(
        solref=(-k, -b),
        solimp=solimp,
        stiffness=k,
        damping=b,
        zeta=b / (2 * math.sqrt(k)),
        duration_s=1e-3,
        max_penetration_m=1e-3,
        restitution=0.8,
        speed_range_mps=(0.5, 10.0),
        timestep_s=DT,
        gravity_mps2=G,
    )


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast", "RK4"])
@pytest.mark.parametrize("solimp", SHAPES)
def test_impedance_emulation_is_mj_step(integrator, solimp):
    """Step by step, MuJoCo's d(r), K = k/dmax^2, B = b/dmax and the constraint's on/off rule
    as mj_step applies them, to 1e-9 (measured 1e-11)."""
    p = _shaped(solimp)
    xml = measure.ball_plane_mjcf(p, radius_m=R, mass_kg=0.057, gravity_mps2=G)
    model = mujoco.MjModel.from_xml_string(
        xml.replace('integrator="Euler"', f'integrator="{integrator}"')
    )
    rule = shaped.contact_rule(np.array(p.solref), np.array(solimp), G)
    v = np.array([0.5, 3.0, 9.0])
    y, u = 0.37 * v * DT, -v
    datas = [mujoco.MjData(model) for _ in v]
    for data, speed in zip(datas, v, strict=True):
        data.qpos[2], data.qvel[2] = R + 0.37 * speed * DT, -speed
    worst = 0.0
    for _ in range(1500):
        y, u, _ = emulation.advance(y, u, DT, rule, emulation.scheme_of(integrator))
        for data in datas:
            mujoco.mj_step(model, data)
        z = np.array([d.qpos[2] - R for d in datas])
        vz = np.array([d.qvel[2] for d in datas])
        worst = max(worst, float(np.max(np.abs(y - z) / 1e-3 + np.abs(u - vz) / v)))
    assert worst < 1e-9


def test_e_is_independent_of_mass_and_radius():
    """The direct form acts on accelerations: the same solref/solimp give the same e for a
    tennis ball and a 1 kg ball of radius 0.1 m."""
    p = _shaped(SHAPES[0])
    for v in (0.7, 4.0):
        small = measure.measure_ball_plane(p, radius_m=0.033, mass_kg=0.057, impact_speed_mps=v)
        big = measure.measure_ball_plane(p, radius_m=0.1, mass_kg=1.0, impact_speed_mps=v)
        assert small.restitution == pytest.approx(big.restitution, abs=1e-9)


def test_rest_sink_is_where_mujoco_rests():
    """A ball left on the floor settles at rest_sink_m (in MuJoCo, after the bounces die)."""
    p = _shaped(SHAPES[0], k=1.3e7, b=1700.0)
    model = mujoco.MjModel.from_xml_string(
        measure.ball_plane_mjcf(p, radius_m=R, mass_kg=0.057, gravity_mps2=G)
    )
    data = mujoco.MjData(model)
    data.qpos[2] = R
    mujoco.mj_step(model, data, nstep=200_000)
    assert abs(data.qvel[2]) < 1e-9
    assert R - data.qpos[2] == pytest.approx(C.rest_sink_m(p), rel=1e-6)


def test_float_keeps_the_closed_form_path():
    p = C.contact_params(0.8, radius_m=0.1, timestep_s=1e-5, speed_range_mps=(0.5, 5.0))
    assert p.curve is None and p.solimp == C.SOLIMP and p.curve_achieved == ()


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"speed_range_mps": (0.3, 5.0)}, "outside the curve's points"),
        ({"speed_range_mps": (1.0, 12.0)}, "outside the curve's points"),
        ({"reference_speed_mps": 20.0}, "outside the speeds"),
        ({"reference_speed_mps": -1.0}, "reference_speed_mps must be a positive number"),
        ({"duration_s": 1e-3, "max_penetration_m": 1e-3}, "not both"),
        ({"radius_m": None}, "give a radius"),
        ({"integrator": "Verlet"}, "integrator must be one of"),
        ({"timestep_s": 0.0}, "timestep_s must be a positive number"),
        # what no fit can do: refused at once, naming what would do
        ({"timestep_s": 1.0}, "timestep 1 s is too coarse for this contact"),
        ({"radius_m": 1e-6}, "a curve needs timestep <= "),
        ({"radius_m": None, "duration_s": 1e-9}, "too coarse"),
        ({"radius_m": 1e3}, "gravity dominates this contact at 0.5 m/s"),
        ({"radius_m": None, "duration_s": 10.0}, "lowest speed >= "),
        ({"gravity_mps2": 1e4}, "gravity dominates"),
    ],
)
def test_bad_requests_for_a_curve(options, message):
    """Refused before any fit, one error naming what is wrong."""
    kwargs = {"radius_m": R, "timestep_s": DT, **options}
    with pytest.raises(C.ContactModelError, match=message):
        C.contact_params(TARGETS["table"], **kwargs)


def test_reference_speed_is_for_curves():
    with pytest.raises(C.ContactModelError, match="reference_speed_mps is for a target e"):
        C.contact_params(
            0.8, radius_m=R, timestep_s=DT, impact_speed_mps=2.0, reference_speed_mps=2.0
        )


@pytest.fixture(scope="module")
def designed() -> dict[str, C.ContactParams]:
    return {
        name: C.contact_params(curve, radius_m=R, timestep_s=DT, gravity_mps2=G)
        for name, curve in TARGETS.items()
    }


@pytest.mark.slow
@pytest.mark.parametrize("name", list(TARGETS))
def test_drop_series_in_plain_mujoco(designed, name):
    """Impacts at 0.5-10 m/s (23 speeds, between the points too, three step phases each),
    each within CURVE_TOLERANCE of the target at its speed, and within the designer's own
    worst case; the penetration within the default bound (10 % of the radius)."""
    p = designed[name]
    curve = TARGETS[name]
    assert p.curve == curve and p.speed_range_mps == curve.span_mps
    assert p.phase_error <= C.CURVE_TOLERANCE
    worst = 0.0
    for v in np.geomspace(0.5, 10.0, 23):
        for phase in (0.1, 0.45, 0.8):
            m = measure.measure_ball_plane(
                p, radius_m=R, mass_kg=0.057, impact_speed_mps=v, gap_m=(1.0 + phase) * v * DT
            )
            speed = -m.v_before_mps[0]
            worst = max(worst, abs(m.restitution - float(curve.at(speed))))
            assert m.max_penetration_m <= 0.1 * R * 1.001
    assert worst <= C.CURVE_TOLERANCE
    assert worst <= p.phase_error + 1e-3


@pytest.mark.slow
def test_a_curve_beyond_reach_names_the_nearest():
    """A drop of 0.30 over 1-10 m/s: refused, with the nearest reachable curve at the user's
    points and its worst error; contact_params(allow_coarse=True) returns that contact."""
    steep = C.RestitutionCurve.of([1, 3, 10], [0.9, 0.75, 0.6])
    with pytest.raises(C.CurveOutOfReach) as caught:
        C.contact_params(steep, radius_m=R, timestep_s=DT)
    text = str(caught.value)
    assert "nearest reachable curve is e = 1:" in text and "worst |e - target|" in text
    nearest = caught.value.design.params
    assert nearest.curve == steep and len(nearest.curve_achieved) == 3
    assert nearest.phase_error > C.CURVE_TOLERANCE
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        again = C.contact_params(steep, radius_m=R, timestep_s=DT, allow_coarse=True)
    assert again == nearest and seen


@pytest.mark.slow
def test_contact_time_at_a_reference_speed(designed):
    """4 ms at 4 m/s for a tennis ball: the time in contact in plain MuJoCo at that speed
    within 5 %, e(v) still within the tolerance, the penetration stated."""
    curve = TARGETS["table"]
    p = C.contact_params(curve, radius_m=R, timestep_s=DT, duration_s=4e-3, reference_speed_mps=4.0)
    assert p.reference_speed_mps == 4.0 and p.restitution == pytest.approx(0.78)
    assert p.duration_s == pytest.approx(4e-3, rel=0.05)
    assert p.phase_error <= C.CURVE_TOLERANCE
    m = measure.measure_ball_plane(p, radius_m=R, mass_kg=0.057, impact_speed_mps=4.0)
    assert abs(m.restitution - 0.78) <= C.CURVE_TOLERANCE
    assert m.max_penetration_m <= p.max_penetration_m * 1.001 * 10.0 / 4.0
