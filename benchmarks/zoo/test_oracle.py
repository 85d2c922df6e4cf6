"""The zoo's oracle against analytic answers and MuJoCo's own numbers."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import oracle
import pytest

MODELS = Path(__file__).resolve().parent / "models"
G = 9.81


def write(folder: Path, xml: str, name: str = "model.xml") -> Path:
    path = folder / name
    path.write_text(xml)
    return path


def ball(*, z: float, radius: float = 0.1, mass: float = 2.0, timestep: float = 1e-3,
         integrator: str = "Euler", floor: bool = True, extra: str = "") -> str:  # fmt: skip
    plane = '<geom name="floor" type="plane" size="5 5 .1"/>' if floor else ""
    return f"""<mujoco><option timestep="{timestep}" integrator="{integrator}"/>
      <worldbody>{plane}
        <body name="ball" pos="0 0 {z}"><freejoint/>
          <geom name="ball" type="sphere" size="{radius}" mass="{mass}" {extra}/></body>
      </worldbody></mujoco>"""


def velocities(path: Path, nsteps: int) -> np.ndarray:
    """qvel at steps 0 .. nsteps from a plain mj_step loop (nsteps + 1, nv)."""
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    out = [d.qvel.copy()]
    for _ in range(nsteps):
        mujoco.mj_step(m, d)
        out.append(d.qvel.copy())
    return np.array(out)


def test_free_fall_euler_energy_and_residual(tmp_path):
    # Semi-implicit Euler: v_k = -g t_k, z_k = z_0 - g t_k (t_k + h) / 2, so the kinetic
    # energy is m g^2 t^2 / 2 and the energy lost by step k is m g^2 h t_k / 2 exactly.
    h, m, z0 = 1e-3, 2.0, 10.0
    run = oracle.run(write(tmp_path, ball(z=z0, mass=m, timestep=h, floor=False)), 0.5)
    t = run.step * h
    assert run.nsteps == 500 and run.step[-1] == 500
    np.testing.assert_allclose(run.time, t, atol=1e-12)
    np.testing.assert_allclose(run.kinetic, 0.5 * m * G**2 * t**2, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(
        run.potential - run.potential[0], -m * G**2 * t * (t + h) / 2, rtol=1e-9, atol=1e-12
    )
    np.testing.assert_allclose(run.residual, -m * G**2 * h * t / 2, rtol=1e-9, atol=1e-12)
    for kind, work in run.work.items():
        assert np.max(np.abs(work)) < 1e-12, kind
    assert run.episodes == () and run.stopped is None


def test_free_fall_rk4_conserves_energy(tmp_path):
    # RK4 integrates constant acceleration exactly: no residual, v = -g t.
    h, m = 1e-3, 2.0
    run = oracle.run(
        write(tmp_path, ball(z=10, mass=m, timestep=h, integrator="RK4", floor=False)), 0.5, 10
    )
    t = run.step * h
    assert run.integrator == "RK4"
    np.testing.assert_allclose(run.kinetic, 0.5 * m * G**2 * t**2, rtol=1e-10)
    assert np.max(np.abs(run.residual)) < 1e-9 * run.energy_scale


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast", "RK4"])
def test_damped_pendulum_loses_its_damping_work(tmp_path, integrator):
    # A hinge pendulum released at 60 degrees (a keyframe): the energy lost equals the work
    # of the joint damping up to a residual of order h; the damping work agrees with
    # -b * integral(omega^2 dt) from a plain loop's velocities.
    b, h, duration = 0.05, 1e-3, 3.0
    xml = f"""<mujoco><option timestep="{h}" integrator="{integrator}"/><worldbody>
      <body name="rod"><joint name="hinge" type="hinge" axis="0 1 0" damping="{b}"/>
        <geom type="capsule" fromto="0 0 0 0 0 -.5" size=".02" mass="1" contype="0" conaffinity="0"/>
      </body></worldbody>
      <keyframe><key name="raised" qpos="{math.radians(60)}"/></keyframe></mujoco>"""
    path = write(tmp_path, xml)
    run = oracle.run(path, duration, 10, keyframe="raised")
    lost = run.energy[-1] - run.energy[0]
    damping = run.work["damper"][-1]
    assert lost < -0.1  # it swings for 3 s and loses a sizeable share
    assert damping < 0
    assert abs(lost - damping) == pytest.approx(abs(run.residual[-1]), abs=1e-12)
    assert abs(run.residual[-1]) < 2e-3 * abs(damping)
    others = [k for k in oracle.WORK_KINDS if k != "damper" and abs(run.work[k][-1]) > 1e-12]
    assert others == []
    m, d = oracle.load(path, keyframe="raised")
    omega = []
    for _ in range(run.nsteps + 1):
        omega.append(d.qvel[0])
        mujoco.mj_step(m, d)
    omega2 = np.array(omega) ** 2
    independent = -b * h * (omega2[:-1] + omega2[1:]).sum() / 2
    assert damping == pytest.approx(independent, rel=1e-3)


def test_ball_onset_time_and_speed(tmp_path):
    # The first step whose state overlaps the floor, on the discrete Euler trajectory
    # z_k = z0 - g h^2 k (k + 1) / 2, and the speed the surfaces met with: that state's, g k h.
    h, z0, r = 1e-3, 1.0, 0.1
    run = oracle.run(write(tmp_path, ball(z=z0, radius=r, timestep=h)), 0.6, 10)
    k = np.arange(1000)
    onset = int(k[z0 - G * h**2 * k * (k + 1) / 2 - r < 0][0])
    (episode,) = run.episodes
    assert {episode.party1, episode.party2} == {"floor", "ball"}
    assert episode.onset_step == onset
    assert episode.onset_time == pytest.approx(onset * h, abs=1e-12)
    assert abs(episode.onset_time - math.sqrt(2 * (z0 - r) / G)) <= h
    assert episode.approach_speed == pytest.approx(G * onset * h, rel=1e-9)
    assert episode.approach_speed == pytest.approx(math.sqrt(2 * G * (z0 - r)), abs=2 * G * h)
    assert episode.max_penetration > 0


def test_calibrated_pair_bounces_with_its_restitution(tmp_path):
    # `impactlab contact` designs a pair for e = 0.8 at 2 m/s (within 0.005 of the target);
    # dropped so that it lands at 2 m/s, the oracle's episode has that e. The oracle takes
    # the speeds one step before onset and at release (gravity changes them by g h = 0.001
    # m/s, 0.0005 of e).
    h, r, speed = 1e-4, 0.05, 2.0
    args = ["--restitution", "0.8", "--radius", str(r), "--speed", str(speed)]
    args += ["--timestep", str(h), "--max-penetration", "0.004", "--json"]
    done = subprocess.run(
        [sys.executable, "-m", "impactlab", "contact", *args],
        capture_output=True,
        text=True,
        check=True,
    )
    design = json.loads(done.stdout)
    assert design["ok"], design.get("problem")
    pair = design["mjcf_pair"].replace("GEOM1", "floor").replace("GEOM2", "ball")
    xml = ball(z=r + speed**2 / (2 * G), radius=r, mass=0.1, timestep=h)
    path = write(tmp_path, xml.replace("</mujoco>", f"<contact>{pair}</contact></mujoco>"))
    run = oracle.run(path, 0.3, 100)
    first = run.episodes[0]
    assert first.approach_speed == pytest.approx(speed, abs=2 * G * h)
    assert first.release_step is not None
    assert first.restitution == pytest.approx(0.8, abs=0.005 + 0.001)


def test_touching_at_t0_has_no_state_before_onset():
    run = oracle.run(MODELS / "stacked_boxes.xml", 0.2, 10)
    (stack,) = [e for e in run.episodes if {e.party1, e.party2} == {"lower", "upper"}]
    assert stack.onset_step == 0 and stack.onset_vn is None
    assert stack.approach_speed is None and stack.restitution is None
    assert stack.release_step is None  # still stacked at the end


def test_massless_foot_is_part_of_its_leg():
    # Issue 35: the foot's geom sits on a massless child body welded to the leg; the leg
    # lands when the foot's bottom (0.95 m up) has fallen: sqrt(2 * 0.95 / g) = 0.440 s.
    run = oracle.run(MODELS / "massless_foot.xml", 0.6, 10)
    (landing,) = run.episodes
    assert (landing.party1, landing.party2) == ("leg", "floor")
    assert abs(landing.onset_time - math.sqrt(2 * 0.95 / G)) <= 2 * run.timestep


def test_strides_log_the_same_values(tmp_path):
    path = write(tmp_path, ball(z=0.5, extra='friction="1"'))
    fine, coarse = oracle.run(path, 0.8, 1), oracle.run(path, 0.8, 10)
    assert np.array_equal(coarse.step, fine.step[::10])
    for kind in oracle.WORK_KINDS:
        np.testing.assert_allclose(coarse.work[kind], fine.work[kind][::10], rtol=0, atol=1e-12)
    np.testing.assert_allclose(coarse.residual, fine.residual[::10], rtol=0, atol=1e-12)
    assert coarse.episodes == fine.episodes and len(fine.episodes) >= 1


@pytest.mark.parametrize("solver", ["converged", "one iteration"])
@pytest.mark.parametrize("cone", ["pyramidal", "elliptic"])
@pytest.mark.parametrize("condim", [1, 3, 6])
def test_contact_works_close_the_kinetic_energy_of_a_sphere(tmp_path, cone, condim, solver):
    # A sphere (constant mass matrix, no gyroscopic torque) thrown spinning onto a plane.
    # With semi-implicit Euler, M dv = h f + (M dv - h f) exactly, so the residual is
    # gravity's discretization m g h (v_z,k - v_z,0) / 2 plus the acceleration gap; the gap
    # is what MuJoCo's solver leaves of M qacc - f: none once converged (up to 1.3e-6 N
    # with elliptic cones and condim 6 even at tolerance 1e-14), much in one
    # iteration with friction.
    h, m = 1e-3, 2.0
    xml = ball(z=0.3, mass=m, timestep=h, extra=f'condim="{condim}" friction="0.6 0.01 0.01"')
    xml = xml.replace('type="plane"', f'type="plane" condim="{condim}"')
    options = 'tolerance="1e-14" iterations="1000"' if solver == "converged" else 'iterations="1"'
    xml = xml.replace("<option ", f'<option cone="{cone}" {options} ')
    xml = xml.replace(
        "</worldbody>", '</worldbody><keyframe><key qvel="1.5 0 -1 0 8 3"/></keyframe>'
    )
    path = write(tmp_path, xml)
    run = oracle.run(path, 0.6, 5, keyframe=0)
    vz = velocities_from_key(path, run.nsteps)[run.step, 2]
    gravity = m * G * h * (vz - vz[0]) / 2
    scale = run.energy_scale
    np.testing.assert_allclose(run.residual, gravity + run.acceleration_gap, atol=1e-11 * scale)
    gap = np.max(np.abs(run.acceleration_gap))
    if solver == "converged":
        assert gap < 1e-8 * scale
    elif condim > 1:  # one frictionless row is solved in one Newton iteration
        assert gap > 1e-6 * scale
    assert run.work["contact_normal"][-1] < 0
    if condim == 1:
        assert np.max(np.abs(run.work["contact_friction"])) < 1e-12
    else:
        assert run.work["contact_friction"][-1] < -1e-3  # it slides and spins on the floor


def velocities_from_key(path: Path, nsteps: int) -> np.ndarray:
    m, d = oracle.load(path, keyframe=0)
    out = [d.qvel.copy()]
    for _ in range(nsteps):
        mujoco.mj_step(m, d)
        out.append(d.qvel.copy())
    return np.array(out)


@pytest.mark.parametrize("cone", ["pyramidal", "elliptic"])
def test_normal_velocity_is_mujocos_own(tmp_path, cone):
    # The onset/release evaluator gives, at the contact's own state, the normal velocity
    # MuJoCo's constraint rows have there (efc_vel).
    xml = ball(z=0.3, timestep=1e-3, extra='condim="3"').replace(
        "<option ", f'<option cone="{cone}" '
    )
    xml = xml.replace(
        "</worldbody>", '</worldbody><keyframe><key qvel="1 .5 -1 2 0 1"/></keyframe>'
    )
    path = write(tmp_path, xml)
    m, d = oracle.load(path, keyframe=0)
    while True:
        mujoco.mj_forward(m, d)
        if d.ncon:
            break
        mujoco.mj_step(m, d)
    state = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_INTEGRATION))
    mujoco.mj_getState(m, d, state, mujoco.mjtState.mjSTATE_INTEGRATION)
    contacts = oracle._Contacts(m, d, m.nbody)
    (vn,) = oracle._NormalVelocity(m)(state, contacts, np.arange(1))
    adr = d.contact.efc_address[0]
    rows = d.efc_vel[adr : adr + 2]
    want = rows.mean() if cone == "pyramidal" else rows[0]
    assert vn == pytest.approx(want, rel=1e-12, abs=1e-15)
    assert vn < 0  # approaching


@pytest.mark.parametrize(
    "model",
    ["humanoid/humanoid.xml", "all_forces.xml", "rope_drop.xml", "inline"],
)
def test_spring_in_potential_is_mujocos_spring_force(tmp_path, model):
    # Joint springs (hinge, slide, ball, free), tendon springs and 1-D flex edges: the force
    # the oracle books as "spring" is all of qfrc_spring, at a moving state.
    if model == "inline":
        path = write(
            tmp_path,
            """<mujoco><option timestep="1e-3"/><worldbody>
            <body pos="0 0 1"><joint type="free" stiffness="3"/><geom size=".1"/>
              <body pos=".3 0 0"><joint type="ball" stiffness="2"/><geom size=".05"/></body>
              <body pos="-.3 0 0"><joint type="slide" axis="1 0 0" stiffness="5" springref=".1"/>
                <geom size=".05"/></body></body></worldbody></mujoco>""",
        )
    else:
        path = MODELS / model
    m, d = oracle.load(path)
    spring = oracle._SpringInPotential(m)
    assert not spring.empty
    for _ in range(400):  # the rope lands at 0.24 s
        mujoco.mj_step(m, d)
    mujoco.mj_forward(m, d)
    assert np.max(np.abs(d.qfrc_spring)) > 1e-6
    np.testing.assert_allclose(spring(d, d.qpos.copy()), d.qfrc_spring, rtol=1e-9, atol=1e-12)


def test_flex_elasticity_is_not_in_the_potential():
    # A 2-D flex's elasticity has no potential in MuJoCo's energy: the oracle books it as
    # "elastic" (non-conservative), and the budget still closes to a small residual.
    run = oracle.run(MODELS / "cloth_drop.xml", 0.5, 10)
    assert abs(run.work["elastic"][-1]) > 1e-4
    assert np.all(run.work["spring"] == 0)
    assert np.max(np.abs(run.residual)) < 0.02 * run.energy_scale


def test_every_kind_of_force_is_booked():
    # all_forces.xml has each kind: each does work, and the budget closes to 2 % of its scale.
    run = oracle.run(MODELS / "all_forces.xml", 1.0, 10)
    expected = {"contact_normal", "limit", "equality", "friction_loss", "damper", "spring"}
    expected |= {"gravcomp", "fluid", "actuator"}
    for kind in expected:
        assert abs(run.work[kind][-1]) > 1e-4, kind
    for kind in ("applied", "passive_other", "constraint_other", "adhesion", "elastic"):
        assert np.max(np.abs(run.work[kind])) < 1e-10, kind
    assert np.max(np.abs(run.residual)) < 0.02 * run.energy_scale


def test_bad_arguments(tmp_path):
    path = write(tmp_path, ball(z=1))
    with pytest.raises(ValueError, match="every must be >= 1"):
        oracle.run(path, 0.1, 0)
    with pytest.raises(ValueError, match="no keyframe named 'nope'"):
        oracle.run(path, 0.1, keyframe="nope")
    with pytest.raises(ValueError, match="keyframe 3 out of range"):
        oracle.run(path, 0.1, keyframe=3)
    with pytest.raises(ValueError, match="shorter than one step"):
        oracle.run(path, 1e-5)
    with pytest.raises(ValueError):  # MuJoCo's own refusal, unchanged
        oracle.run(
            write(
                tmp_path, "<mujoco><worldbody><geom type='nope'/></worldbody></mujoco>", "bad.xml"
            ),
            0.1,
        )


def test_gravity_potential_is_the_potential_less_the_springs(tmp_path):
    # No spring: the two agree. all_forces.xml at its start: the shoulder's spring is 30
    # degrees from its rest (k = 2) and the tendon cord from (0, 0, 1.4) to the elbow site
    # (0.4, 0, 1) is 0.2 m long at rest (k = 50).
    run = oracle.run(write(tmp_path, ball(z=1)), 0.3, 10)
    assert run.gravity_potential is not None
    np.testing.assert_allclose(run.gravity_potential, run.potential, rtol=1e-12)
    forces = oracle.run(MODELS / "all_forces.xml", 0.2, 10)
    assert forces.gravity_potential is not None
    cord = math.hypot(0.4, 0.4) - 0.2
    springs = 0.5 * 2 * math.radians(30) ** 2 + 0.5 * 50 * cord**2
    assert forces.potential[0] - forces.gravity_potential[0] == pytest.approx(springs, rel=1e-9)


@pytest.mark.parametrize("model", ["rope_drop.xml", "all_forces.xml", "cloth_drop.xml"])
def test_springs_booked_as_work_close_the_budget_too(model):
    run = oracle.run(MODELS / model, 0.5, 10)
    other = oracle.springs_booked_as_work(run)
    assert other.gravity_potential is not None
    np.testing.assert_array_equal(other.potential, run.gravity_potential)
    np.testing.assert_allclose(other.work["spring"], run.work["spring"] + run.work["elastic"])
    assert np.all(other.work["elastic"] == 0)
    assert np.max(np.abs(other.residual)) < 0.02 * run.energy_scale
    spring_potential = run.potential - run.gravity_potential
    np.testing.assert_allclose(
        other.residual - run.residual,
        -(spring_potential - spring_potential[0]) - run.work["spring"],
        atol=1e-12 * run.energy_scale,
    )


def test_flex_is_a_party_of_its_own():
    # Issue 35: the 3 x 3 x 3 flexcomp's bottom vertices (0.4 m up, radius 0.005) land at
    # sqrt(2 * 0.395 / g) = 0.284 s, nine contacts at once.
    run = oracle.run(MODELS / "flexcomp_drop.xml", 0.4, 10)
    landing = run.episodes[0]
    assert (landing.party1, landing.party2) == ("flex cube", "floor")
    assert abs(landing.onset_time - math.sqrt(2 * 0.395 / G)) <= 2 * run.timestep
    assert landing.onset_vn is not None and len(landing.onset_vn) == 9


def test_onset_speed_of_a_jointed_body_is_its_contact_points(tmp_path):
    # A hinged rod swings down onto a box: the onset normal velocity is n . J_p qvel of the
    # rod's contact point at the onset state (mj_jac), not its centre's velocity.
    xml = """<mujoco><option timestep="1e-3"/><worldbody>
      <geom name="block" type="box" size=".1 .1 .1" pos=".5 0 .1"/>
      <body name="rod" pos="0 0 .5"><joint type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 .6 0 0" size=".02"/></body>
      </worldbody></mujoco>"""
    path = write(tmp_path, xml)
    run = oracle.run(path, 1.0, 10)
    hit = run.episodes[0]
    assert (hit.party1, hit.party2) == ("rod", "block") and hit.onset_vn is not None
    m, d = oracle.load(path)
    for _ in range(hit.onset_step):
        mujoco.mj_step(m, d)
    mujoco.mj_forward(m, d)  # the onset state and its contacts
    (contact,) = d.contact
    jacp = np.zeros((3, m.nv))
    mujoco.mj_jac(m, d, jacp, None, contact.pos, m.body("rod").id)
    normal = contact.frame[:3]
    sign = 1.0 if m.geom_bodyid[contact.geom2] == m.body("rod").id else -1.0
    assert hit.onset_vn[0] == pytest.approx(sign * normal @ jacp @ d.qvel, rel=1e-9)
    assert abs(hit.onset_vn[0]) > 1.0  # the tip moves much faster than the rod's centre
