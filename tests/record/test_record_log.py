"""What a recorded log holds, read back with the official mcap reader and checked against physics."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
from paths import EXPERIMENTS
from specs import DIRECT, drop, toml

from impactlab.cli import main
from impactlab.logs import format as logformat
from impactlab.record import plan, record_runs

# k = 1e5, zeta = 0.1: e = 0.744
BOUNCY = toml(drop("bouncy", z=0.6, timestep=0.0001, contact=DIRECT, max_time=5.0, bounces=2))


def record_text(tmp_path: Path, text: str, *overrides: str) -> list[Path]:
    spec = tmp_path / "spec.toml"
    spec.write_text(text)
    results = record_runs(plan([spec], overrides=overrides), tmp_path / "logs")
    return [r.path for r in results]


def read_all(path: Path):
    """Every message of every channel, decoded by the official reader and protobuf decoder."""
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        msgs = [(ch.topic, m.log_time, proto) for _, ch, m, proto in reader.iter_decoded_messages()]
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        attachments = {a.name: a.data for a in reader.iter_attachments()}
        header = reader.get_header()
    return summary, msgs, meta, attachments, header


@pytest.fixture(scope="module")
def bouncy_log(tmp_path_factory) -> Path:
    (path,) = record_text(tmp_path_factory.mktemp("bouncy"), BOUNCY)
    return path


@pytest.mark.slow
def test_channels_schemas_and_counts(bouncy_log):
    summary, msgs, _, _, header = read_all(bouncy_log)
    topics = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert topics == {
        "/scene": "foxglove.SceneUpdate",
        "/bodies/ball/state": "impactlab.BodyState",
        "/bodies/ball/clearance": "impactlab.Clearance",
        "/contacts": "impactlab.Contacts",
        "/impacts": "impactlab.Impact",
        "/energy": "impactlab.Energy",
        "/energy/work": "impactlab.Work",
        "/tf": "foxglove.FrameTransforms",
        "/events": "foxglove.Log",
    }
    assert header.library.startswith("impactlab ")
    assert all(s.id > 0 for s in summary.schemas.values())
    assert summary.statistics.message_count == len(msgs)
    assert {c.compression for c in summary.chunk_indexes} == {"zstd"}
    counts = {t: sum(1 for m in msgs if m[0] == t) for t in topics}
    assert counts["/bodies/ball/state"] == counts["/energy"] == counts["/tf"]
    assert counts["/bodies/ball/clearance"] == counts["/energy"]
    assert counts["/energy/work"] == counts["/energy"]
    assert 0 < counts["/contacts"] < counts["/energy"]
    assert counts["/impacts"] == 2  # one message per contact episode, at its release
    assert counts["/scene"] == 1


@pytest.mark.slow
def test_timestamps_are_sim_time_and_strictly_increasing(bouncy_log):
    _, msgs, meta, _, _ = read_all(bouncy_log)
    for topic in ("/bodies/ball/state", "/energy", "/tf", "/contacts", "/impacts"):
        times = np.array([t for tp, t, _ in msgs if tp == topic])
        assert times.size > 1 and (np.diff(times) > 0).all(), topic
        assert (times % 100_000 == 0).all()  # multiples of the 0.1 ms timestep, in ns
    state_times = [t for tp, t, _ in msgs if tp == "/bodies/ball/state"]
    assert state_times[0] == 0
    steps = int(meta[logformat.OUTCOME_METADATA]["steps"])
    assert state_times[-1] == (steps - 1) * 100_000


@pytest.mark.slow
def test_metadata_and_attachment_reproduce_the_run(bouncy_log):
    _, msgs, meta, attachments, _ = read_all(bouncy_log)
    run = meta[logformat.RUN_METADATA]
    assert set(run) == set(logformat.RUN_KEYS)
    assert set(meta[logformat.OUTCOME_METADATA]) == set(logformat.OUTCOME_KEYS)
    assert run["mujoco_version"] == mujoco.__version__
    assert json.loads(run["spec"])["bodies"]["ball"]["pos"] == [0.0, 0.0, 0.6]
    assert len(run["spec_hash"]) == 64
    # the attached MJCF alone reproduces the logged trajectory through the first bounce, bit
    # for bit within the first rollout chunk (1 s; later chunks restart the solver's warm
    # start, ~1e-12); MuJoCo's own saved XML (6 digits) would miss by ~1e-4
    model = mujoco.MjModel.from_xml_string(attachments[logformat.MODEL_ATTACHMENT].decode())
    assert model.pair_solref.size == 0 and model.geom_solref[1][1] == -63.245553
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("initial").id)
    states = [m for tp, _, m in msgs if tp == "/bodies/ball/state"]
    for step in range(4500):
        if step % 250 == 0:
            logged = [states[step].x, states[step].y, states[step].z, states[step].vz]
            assert [*data.qpos[0:3], data.qvel[2]] == logged
        mujoco.mj_step(model, data)
    assert states[4000].vz > 0  # past the first bounce


@pytest.mark.slow
def test_bounce_stop_ends_at_the_apex_after_the_last_bounce(bouncy_log):
    _, msgs, meta, _, _ = read_all(bouncy_log)
    assert meta[logformat.OUTCOME_METADATA]["reason"] == "apex after bounce 2"
    vz = np.array([m.vz for tp, _, m in msgs if tp == "/bodies/ball/state"])
    z = np.array([m.z for tp, _, m in msgs if tp == "/bodies/ball/state"])
    assert vz[-2] > 0 >= vz[-1]  # the last row is the first one past the apex
    # apex height above contact ~ e^4 * drop height (e = 0.744 at zeta = 0.1), within 3 %
    e = 0.7441
    assert z[-1] - 0.1 == pytest.approx(e**4 * 0.5, rel=0.03)


@pytest.mark.slow
def test_contact_messages_carry_force_and_geometry(bouncy_log):
    _, msgs, _, _, _ = read_all(bouncy_log)
    summary = read_all(bouncy_log)[0]
    channel = next(c for c in summary.channels.values() if c.topic == "/contacts")
    geoms, bodies = json.loads(channel.metadata["geoms"]), json.loads(channel.metadata["bodies"])
    contacts = [m for tp, _, m in msgs if tp == "/contacts"]
    assert all(len(c.points) == 1 for c in contacts)  # a sphere on a plane: one point
    first = contacts[0].points[0]
    sides = (geoms[first.geom1], geoms[first.geom2], bodies[first.geom1], bodies[first.geom2])
    assert sides == ("plane", "ball", "plane", "ball")  # a static geom is its own party
    p = first
    assert (p.nx, p.ny, p.nz) == (0.0, 0.0, 1.0)  # from the plane into the ball
    # first bounce: impulse = m (v_in + v_out) + m g T (gravity acts during the contact too)
    times = np.array([t for tp, t, _ in msgs if tp == "/contacts"])
    first_bounce = np.flatnonzero(np.diff(times) > 100_000)[0] + 1
    forces = np.array([c.points[0].normal_force for c in contacts[:first_bounce]])
    v_in, e, duration = np.sqrt(2 * 9.81 * 0.5), 0.7441, first_bounce * 1e-4
    expected = v_in * (1 + e) + 9.81 * duration
    assert forces.sum() * 1e-4 == pytest.approx(expected, rel=0.02)
    assert all(c.points[0].fz == pytest.approx(c.points[0].normal_force) for c in contacts)
    assert max(c.points[0].penetration for c in contacts) > 0


@pytest.mark.slow
def test_free_flight_follows_the_parabola(bouncy_log):
    _, msgs, _, _, _ = read_all(bouncy_log)
    states = [(t / 1e9, m) for tp, t, m in msgs if tp == "/bodies/ball/state"]
    t = np.array([s[0] for s in states[:2000]])
    z = np.array([s[1].z for s in states[:2000]])
    # semi-implicit Euler: z_n = z0 - g dt^2 n (n + 1) / 2, exact to rounding
    n = np.rint(t / 1e-4)
    assert np.allclose(z, 0.6 - 9.81 * 1e-8 * n * (n + 1) / 2, atol=1e-12)
    assert np.allclose(z, 0.6 - 9.81 * t**2 / 2, atol=9.81 * 1e-4 * t.max())


def test_at_rest_stop(tmp_path):
    text = (EXPERIMENTS / "free_fall.toml").read_text()
    (path,) = record_text(tmp_path, text, "ball.pos=[0, 0, 0.5]")
    _, msgs, meta, _, _ = read_all(path)
    assert meta[logformat.OUTCOME_METADATA]["reason"] == "bodies at rest"
    last = [m for tp, _, m in msgs if tp == "/bodies/ball/state"][-50:]
    assert all(np.linalg.norm([m.vx, m.vy, m.vz]) < 1e-3 for m in last)


@pytest.mark.slow
def test_collision_stops_when_separated(tmp_path):
    (path,) = record_text(tmp_path, (EXPERIMENTS / "collision.toml").read_text())
    _, msgs, meta, _, _ = read_all(path)
    assert meta[logformat.OUTCOME_METADATA]["reason"] == "bodies separated by 0.2 m"
    assert json.loads(meta[logformat.OUTCOME_METADATA]["warnings"]) == []
    b1 = [m for tp, _, m in msgs if tp == "/bodies/ball1/state"]
    b2 = [m for tp, _, m in msgs if tp == "/bodies/ball2/state"]
    gap = b2[-1].x - b1[-1].x - 0.2
    assert 0.2 <= gap < 0.2 + 1e-3
    p0 = b1[0].vx + b2[0].vx
    assert b1[-1].vx + b2[-1].vx == pytest.approx(p0, rel=1e-12)


@pytest.mark.slow
def test_handout_step3_as_written_warns(tmp_path, capsys):
    spec = EXPERIMENTS / "collision.toml"
    code = main(["record", str(spec), "--set", "stop.max_time=0.5", "-o", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0
    assert "warning: collision-" in out and "no contact between the bodies" in out
    (path,) = tmp_path.glob("*.mcap")
    _, msgs, meta, _, _ = read_all(path)
    warnings = json.loads(meta[logformat.OUTCOME_METADATA]["warnings"])
    assert len(warnings) == 1 and "never happened" in warnings[0]
    events = [m for tp, _, m in msgs if tp == "/events"]
    assert any(e.level == e.WARNING and "no contact" in e.message for e in events)
    assert not any(tp.startswith("/contacts") for tp, _, _ in msgs)


def test_generic_mjcf_with_a_box(tmp_path, capsys):
    model = tmp_path / "box.xml"
    model.write_text(
        """<mujoco><worldbody><geom type="plane" size="1 1 0.1"/>
        <body pos="0 0 0.3"><freejoint/><geom type="box" size="0.05 0.05 0.05"/></body>
        <body name="b" pos="0.5 0 0.3"><freejoint/><geom name="s" type="sphere" size="0.05"/></body>
        </worldbody></mujoco>"""
    )
    assert main(["record", str(model), "--duration", "0.5", "-o", str(tmp_path / "logs")]) == 0
    (path,) = (tmp_path / "logs").glob("box-*.mcap")
    summary, msgs, meta, _, _ = read_all(path)
    topics = {c.topic for c in summary.channels.values()}
    assert {"/bodies/body1/state", "/bodies/b/state", "/contacts"} <= topics
    channel = next(c for c in summary.channels.values() if c.topic == "/contacts")
    geoms = json.loads(channel.metadata["geoms"])
    assert geoms[:3] == ["geom0", "geom1", "s"]  # unnamed geoms get their index's name
    contacts = [m for tp, _, m in msgs if tp == "/contacts"]
    box = [[p for p in m.points if (p.geom1, p.geom2) == (0, 1)] for m in contacts]
    assert max(len(points) for points in box) == 4  # a box resting flat touches at 4 corners
    assert meta[logformat.OUTCOME_METADATA]["reason"] == "time limit 0.5 s"


def test_no_partial_files_remain(bouncy_log):
    assert not list(bouncy_log.parent.glob("*.partial"))


def test_info_describes_a_log(bouncy_log, capsys):
    assert main(["info", str(bouncy_log)]) == 0
    out = capsys.readouterr().out
    assert "experiment: bouncy" in out and "apex after bounce 2" in out
    assert "/contacts " in out and "impactlab.Contacts" in out


def _rerun() -> str:
    exe = Path(sys.executable).with_name("rerun")
    return str(exe) if exe.exists() else shutil.which("rerun") or "rerun"


@pytest.mark.slow
def test_rerun_converts_the_log_and_its_poses(bouncy_log, tmp_path):
    check = subprocess.run(
        [_rerun(), "mcap", "check", str(bouncy_log)], capture_output=True, text=True
    )
    assert check.returncode == 0, check.stdout + check.stderr
    rrd = tmp_path / "out.rrd"
    conv = subprocess.run(
        [_rerun(), "mcap", "convert", str(bouncy_log), "-o", str(rrd)],
        capture_output=True,
        text=True,
    )
    assert conv.returncode == 0, conv.stderr
    printed = subprocess.run([_rerun(), "rrd", "print", str(rrd)], capture_output=True, text=True)
    assert "/tf" in printed.stdout and "Transform3D:translation" in printed.stdout
    assert "/bodies/ball/state" in printed.stdout
