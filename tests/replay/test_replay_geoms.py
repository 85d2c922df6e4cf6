"""Replays draw the model from the log alone: every geom with its type, size and colour.

Models written here (primitives, an inline mesh, an articulated body with an OBJ mesh link)
are recorded, replayed, and the recordings read back with Rerun's own reader
(`rerun.chunk.RrdReader`); the log's Foxglove `/scene` and `/tf` are read back with the
official MCAP reader and `foxglove_schemas_protobuf`. Expected values come from MuJoCo's
compiled model, not from the code under test.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
import pytest
import rerun as rr
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
from paths import GOLDEN
from specs import collision, drop, toml
from waiting import wait_until

from impactlab.logs.geoms import SCENE_METADATA, decode_stl, read_scene
from impactlab.logs.load import load_log
from impactlab.logs.reader import read_attachments
from impactlab.record import plan, record_runs
from impactlab.replay.convert import run_prefix
from impactlab.replay.recordings import replay_logs

PRIMITIVES = """
<mujoco model="primitives">
  <asset>
    <material name="teal" rgba="0 0.6 0.6 1"/>
    <mesh name="wedge" vertex="0 0 0  0.2 0 0  0 0.1 0  0 0 0.1  0.2 0 0.1  0 0.1 0.1"
          face="0 2 1  3 4 5  0 1 4  0 4 3  0 3 5  0 5 2  1 2 5  1 5 4"/>
    <hfield name="bumps" nrow="3" ncol="4" elevation="0 1 0 1  1 0 1 0  0 1 0 1"
            size="0.3 0.2 0.05 0.01"/>
  </asset>
  <worldbody>
    <geom name="floor" type="plane" size="3 3 0.1" rgba="0.7 0.7 0.7 1"/>
    <geom name="table" type="box" size="0.4 0.3 0.02" pos="0 1 0.3" euler="0 0 30"
          material="teal"/>
    <geom name="bumps" type="hfield" hfield="bumps" pos="1.5 1.5 0" rgba="0.4 0.3 0.2 1"/>
    <geom name="hidden" type="box" size="0.1 0.1 0.1" pos="0 -1 0.1" group="3"/>
    <body name="box" pos="-1 0 0.3">
      <freejoint/>
      <geom name="box" type="box" size="0.1 0.05 0.04" rgba="0.9 0.1 0.1 1"/>
    </body>
    <body name="capsule" pos="-0.5 0 0.3" euler="0 90 0">
      <freejoint/>
      <geom name="capsule" type="capsule" size="0.04 0.1" rgba="0.1 0.9 0.1 1"/>
    </body>
    <body name="cylinder" pos="0 0 0.3">
      <freejoint/>
      <geom name="cylinder" type="cylinder" size="0.06 0.08" rgba="0.1 0.1 0.9 1"/>
    </body>
    <body name="ellipsoid" pos="0.5 0 0.3">
      <freejoint/>
      <geom name="ellipsoid" type="ellipsoid" size="0.1 0.06 0.04" rgba="0.9 0.9 0.1 1"/>
    </body>
    <body name="wedge" pos="1 0 0.3">
      <freejoint/>
      <geom name="wedge" type="mesh" mesh="wedge" rgba="0.9 0.1 0.9 1"/>
    </body>
  </worldbody>
</mujoco>
"""

# An articulated body: a free torso with two hinged legs, one leg ending in an OBJ mesh foot.
WALKER = """
<mujoco model="walker">
  <compiler meshdir="."/>
  <asset>
    <mesh name="foot" file="foot.obj"/>
    <material name="orange" rgba="1 0.5 0 1"/>
  </asset>
  <worldbody>
    <geom name="ground" type="plane" size="0 0 0.1" rgba="0.6 0.6 0.65 1"/>
    <body name="torso" pos="0 0 0.6">
      <freejoint/>
      <geom name="torso" type="box" size="0.15 0.1 0.05" rgba="0 0.8 0.8 1"/>
      <geom name="head" type="sphere" size="0.06" pos="0.18 0 0.05" rgba="0.95 0.95 0.95 1"/>
      <body name="thigh" pos="0 0.06 -0.05">
        <joint name="hip" type="hinge" axis="0 1 0" range="-60 60"/>
        <geom name="thigh" type="capsule" fromto="0 0 0 0 0 -0.2" size="0.03" material="orange"/>
        <body name="foot" pos="0 0 -0.23">
          <joint name="ankle" type="hinge" axis="0 1 0" range="-30 30"/>
          <geom name="foot" type="mesh" mesh="foot" rgba="0.9 0 0.9 1"/>
        </body>
      </body>
      <body name="leg2" pos="0 -0.06 -0.05">
        <joint name="hip2" type="hinge" axis="0 1 0" range="-60 60"/>
        <geom name="leg2" type="cylinder" fromto="0 0 0 0 0 -0.25" size="0.025" material="orange"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

# A wedge 0.16 x 0.08 x 0.04 m under the ankle (OBJ faces are 1-based, counter-clockwise).
FOOT_OBJ = """\
v -0.05 -0.04 0
v 0.11 -0.04 0
v -0.05 0.04 0
v 0.11 0.04 0
v -0.05 -0.04 -0.04
v 0.11 -0.04 -0.04
v -0.05 0.04 -0.04
v 0.11 0.04 -0.04
f 1 2 4
f 1 4 3
f 5 7 8
f 5 8 6
f 1 5 6
f 1 6 2
f 3 4 8
f 3 8 7
f 1 3 7
f 1 7 5
f 2 6 8
f 2 8 4
"""


def _record(folder: Path, name: str, xml: str, files: dict[str, str] | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for fname, text in (files or {}).items():
        (folder / fname).write_text(text)
    path = folder / f"{name}.xml"
    path.write_text(xml)
    (result,) = record_runs(
        plan([path], overrides=["stop.max_time=0.2", "logging.every=10"]), folder / "logs"
    )
    return result.path


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, mujoco.MjModel]]:
    """The two models recorded once, with MuJoCo's own compiled model of each."""
    root = tmp_path_factory.mktemp("geoms")
    out = {}
    for name, xml, files in (
        ("primitives", PRIMITIVES, None),
        ("walker", WALKER, {"foot.obj": FOOT_OBJ}),
    ):
        log = _record(root / name, name, xml, files)
        model = mujoco.MjModel.from_xml_path(str(root / name / f"{name}.xml"))
        out[name] = (log, model)
    return out


def _expected(model: mujoco.MjModel) -> dict[str, dict]:
    """Per visible geom (group 0-2): type, size, rgba 0-255 and triangle count, from MuJoCo."""
    out = {}
    for g in range(model.ngeom):
        if model.geom_group[g] > 2:
            continue
        rgba = model.geom_rgba[g]
        if model.geom_matid[g] >= 0 and np.allclose(rgba, [0.5, 0.5, 0.5, 1]):
            rgba = model.mat_rgba[model.geom_matid[g]]
        kind = mujoco.mjtGeom(int(model.geom_type[g])).name.removeprefix("mjGEOM_").lower()
        faces = int(model.mesh_facenum[model.geom_dataid[g]]) if kind == "mesh" else 0
        if kind == "hfield":
            h = model.geom_dataid[g]
            faces = 2 * int(model.hfield_nrow[h] - 1) * int(model.hfield_ncol[h] - 1)
        out[model.geom(g).name] = {
            "type": kind,
            "size": np.array(model.geom_size[g]),
            "rgba": tuple(round(255 * float(c)) for c in rgba),
            "body": model.body(model.geom_bodyid[g]).name,
            "faces": faces,
        }
    return out


def _static_chunks(rrd: Path) -> dict[str, dict[str, object]]:
    """Every static component of the recording, by entity path (Rerun's own reader)."""
    out: dict[str, dict[str, object]] = defaultdict(dict)
    for chunk in rr.chunk.RrdReader(rrd).stream():
        if chunk.is_static:
            row = chunk.to_record_batch().to_pylist()[-1]
            out[chunk.entity_path].update({k: v for k, v in row.items() if ":" in k})
    return out


def _same_color(got, want) -> None:
    """0-255 colours equal within one unit (MuJoCo keeps float32, which rounds either way)."""
    assert np.max(np.abs(np.subtract(got, want))) <= 1, (got, want)


def _unpack(color: int) -> tuple[int, int, int, int]:
    return tuple(int(color) >> s & 0xFF for s in (24, 16, 8, 0))  # type: ignore[return-value]


ARCHETYPE = {
    "box": "Boxes3D",
    "plane": "Boxes3D",
    "sphere": "Ellipsoids3D",
    "ellipsoid": "Ellipsoids3D",
    "capsule": "Capsules3D",
    "cylinder": "Cylinders3D",
    "mesh": "Mesh3D",
    "hfield": "Mesh3D",
}


@pytest.mark.parametrize("name", ["primitives", "walker"])
def test_every_geom_is_drawn_with_its_type_size_and_colour(models, name, tmp_path):
    log, model = models[name]
    run = load_log(log)
    rrd = tmp_path / "r.rrd"
    replay_logs([log], out=rrd, analysis_dir=None)
    static = _static_chunks(rrd)
    prefix = f"{run_prefix(run.run_id)}/world"
    table = {g.name: g for g in read_scene(run.scene, read_attachments(log)).geoms}
    expected = _expected(model)
    drawn = {p.rsplit("/", 1)[-1] for p in static if "/geoms/" in p or "/static/" in p}
    assert drawn == set(expected)  # every visible geom, not the group-3 one
    assert name != "primitives" or not table["hidden"].visible  # in the table, not drawn
    for geom, want in expected.items():
        on = table[geom].body
        # drawn on its own body when that body's pose is logged, else the nearest logged ancestor
        b = model.body(want["body"]).id
        while b and model.body(b).name not in run.bodies:
            b = model.body_parentid[b]
        assert on == (model.body(b).name if b and model.body_weldid[b] else "world")
        path = f"{prefix}/static/{geom}" if on == "world" else f"{prefix}/bodies/{on}/geoms/{geom}"
        components = static[path]
        arch = ARCHETYPE[want["type"]]
        a, b_, c = want["size"]
        if arch == "Mesh3D":
            (albedo,) = components["Mesh3D:albedo_factor"]
            _same_color(_unpack(albedo), want["rgba"])
            assert len(components["Mesh3D:vertex_positions"]) == 3 * want["faces"] > 0
            continue
        (color,) = components[f"{arch}:colors"]
        _same_color(_unpack(color), want["rgba"])
        if want["type"] == "box":
            np.testing.assert_allclose(components["Boxes3D:half_sizes"], [[a, b_, c]], rtol=1e-6)
        elif want["type"] == "plane":
            half = components["Boxes3D:half_sizes"][0]
            assert half[2] == pytest.approx(0.0005)  # a thin slab cut around the bodies
            assert 0 < half[0] <= (a if a > 0 else 5.0) + 1e-6
        elif want["type"] == "sphere":
            np.testing.assert_allclose(components["Ellipsoids3D:half_sizes"], [[a] * 3], rtol=1e-6)
        elif want["type"] == "ellipsoid":
            np.testing.assert_allclose(
                components["Ellipsoids3D:half_sizes"], [[a, b_, c]], rtol=1e-6
            )
        elif want["type"] == "capsule":
            assert components["Capsules3D:radii"] == pytest.approx([a])
            assert components["Capsules3D:lengths"] == pytest.approx([2 * b_])
        elif want["type"] == "cylinder":
            assert components["Cylinders3D:radii"] == pytest.approx([a])
            assert components["Cylinders3D:lengths"] == pytest.approx([2 * b_])


def _world_pose(run, table, geom: str) -> tuple[np.ndarray, np.ndarray]:
    """A geom's world position and rotation at t = 0 from the log alone (table + first state)."""
    g = table[geom]
    rot_g = _rot(g.quat)
    if g.body == "world":
        return np.asarray(g.pos), rot_g
    s = run.bodies[g.body].row(0, named=True)
    rot_b = _rot((s["qw"], s["qx"], s["qy"], s["qz"]))
    return np.array([s["x"], s["y"], s["z"]]) + rot_b @ g.pos, rot_b @ rot_g


def _rot(q) -> np.ndarray:
    mat = np.empty(9)
    mujoco.mju_quat2Mat(mat, np.asarray(q, dtype=float))
    return mat.reshape(3, 3)


@pytest.mark.parametrize("name", ["primitives", "walker"])
def test_geom_poses_and_meshes_from_the_log_match_mujoco(models, name):
    """Each geom placed by the log's table on its body's first logged pose is where MuJoCo
    puts it at the start of the run; the mesh triangles are MuJoCo's."""
    log, model = models[name]
    run = load_log(log)
    scene = read_scene(run.scene, read_attachments(log))
    assert not scene.problems
    table = {g.name: g for g in scene.geoms}
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)  # the runs start at qpos0 (no keyframe)
    for g in range(model.ngeom):
        pos, rot = _world_pose(run, table, model.geom(g).name)
        np.testing.assert_allclose(pos, data.geom_xpos[g], atol=1e-9)
        np.testing.assert_allclose(rot, data.geom_xmat[g].reshape(3, 3), atol=1e-9)
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
            m = model.geom_dataid[g]
            v0, f0 = model.mesh_vertadr[m], model.mesh_faceadr[m]
            vert = model.mesh_vert[v0 : v0 + model.mesh_vertnum[m]]
            faces = model.mesh_face[f0 : f0 + model.mesh_facenum[m]]
            tri = scene.meshes[table[model.geom(g).name].mesh]
            np.testing.assert_allclose(tri, vert[faces], atol=1e-6)  # float32 in the STL
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_HFIELD:  # spans x, y and 0..top
            sx, sy, top, _ = model.hfield_size[model.geom_dataid[g]]
            tri = scene.meshes[table[model.geom(g).name].mesh].reshape(-1, 3)
            np.testing.assert_allclose(tri.min(axis=0), [-sx, -sy, 0.0], atol=1e-6)
            np.testing.assert_allclose(tri.max(axis=0), [sx, sy, top], atol=1e-6)


def _foxglove(log: Path):
    with open(log, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        scene = tf = None
        tf = []
        for _, channel, message, decoded in reader.iter_decoded_messages(topics=["/scene", "/tf"]):
            if channel.topic == "/scene":
                scene = decoded
            else:
                tf.append((message.log_time, decoded))
        attachments = {a.name: a.data for a in reader.iter_attachments()}
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    return scene, tf, attachments, metadata


@pytest.mark.parametrize("name", ["primitives", "walker"])
def test_foxglove_scene_has_the_same_entities_and_tf_is_stamped(models, name):
    log, model = models[name]
    scene, tf, attachments, metadata = _foxglove(log)
    table = {g.name: g for g in read_scene(metadata[SCENE_METADATA], attachments).geoms}
    expected = _expected(model)
    entities = {e.id: e for e in scene.entities}
    assert set(entities) == set(expected)
    for geom, want in expected.items():
        e = entities[geom]
        assert e.frame_id == table[geom].body
        kind = want["type"]
        prims = {
            "box": e.cubes,
            "plane": e.cubes,
            "sphere": e.spheres,
            "ellipsoid": e.spheres,
            "cylinder": e.cylinders,
            "capsule": e.cylinders,
            "mesh": e.models,
            "hfield": e.models,
        }[kind]
        assert len(prims) == 1, geom
        p = prims[0]
        color = tuple(round(255 * c) for c in (p.color.r, p.color.g, p.color.b, p.color.a))
        _same_color(color, want["rgba"])
        a, b, c = want["size"]
        if kind == "box":
            assert (p.size.x, p.size.y, p.size.z) == pytest.approx((2 * a, 2 * b, 2 * c))
        elif kind in ("sphere", "ellipsoid"):
            radii = (a, a, a) if kind == "sphere" else (a, b, c)
            assert (p.size.x, p.size.y, p.size.z) == pytest.approx(tuple(2 * r for r in radii))
        elif kind in ("cylinder", "capsule"):
            assert (p.size.x, p.size.z) == pytest.approx((2 * a, 2 * b))
            assert len(e.spheres) == (2 if kind == "capsule" else 0)
        elif kind in ("mesh", "hfield"):
            assert p.media_type == "model/stl"
            assert len(decode_stl(p.data)) == want["faces"]
            assert p.data == attachments[table[geom].mesh]
    times = np.array([t for t, _ in tf], dtype=np.int64)
    stamps = np.array(
        [[x.timestamp.ToNanoseconds() for x in msg.transforms] for _, msg in tf], dtype=np.int64
    )
    assert np.all(np.diff(times) > 0) and times[-1] > 0
    np.testing.assert_array_equal(stamps, np.repeat(times[:, None], stamps.shape[1], axis=1))
    children = {x.child_frame_id for x in tf[0][1].transforms}
    assert {e.frame_id for e in scene.entities} - {"world"} <= children


# --- the viewer draws the model ---------------------------------------------------------------
#
# The native viewer (`rerun FILE.rrd`) cannot start on a machine without a GPU here: with
# Mesa's llvmpipe (OpenGL) wgpu reports no R32Float render target, which the viewer needs,
# and no Vulkan software driver (lavapipe) is installed. The same viewer built for the web,
# which the `rerun` binary of rerun-sdk serves (`--serve-web`), renders in Chromium with its
# software GPU (SwiftShader); Chromium runs on an Xvfb display and `import` (ImageMagick)
# takes the screenshot.

VIEWER_TOOLS = ("Xvfb", "chromium", "import")
MODEL_HUES = {"torso (cyan)": 180.0, "legs (orange)": 30.0, "foot (magenta)": 300.0}
SCREEN = (1600, 1000)


def _free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _free_display() -> int:
    for n in range(140, 400):
        if not Path(f"/tmp/.X11-unix/X{n}").exists() and not Path(f"/tmp/.X{n}-lock").exists():
            return n
    raise RuntimeError("no free X display number")


MODEL_VIEW = (0.0, 0.05, 0.4, 0.65)  # the 3D view in the replay's layout (x0, y0, x1, y1)
PLOTS = (0.41, 0.05, 1.0, 0.97)  # its plots


def _screen(png: Path, region: tuple[float, float, float, float]) -> np.ndarray:
    """The region (x0, y0, x1, y1 as fractions of the screen) of a screenshot, RGB in 0..1."""
    import matplotlib.image

    image = matplotlib.image.imread(png)
    if image.ndim == 2:  # ImageMagick writes a screen of greys only (a blank page) as grey
        image = image[..., None]
    if image.shape[-1] < 3:  # grey, or grey and alpha: the grey as R, G and B
        image = np.repeat(image[..., :1], 3, axis=-1)
    image = image[..., :3]
    h, w = image.shape[:2]
    x0, y0, x1, y1 = region
    return image[int(y0 * h) : int(y1 * h), int(x0 * w) : int(x1 * w)]


def hue_pixels(png: Path, region: tuple[float, float, float, float]) -> dict[str, int]:
    """Pixels of each model colour's hue (within 12 degrees, saturated, not dark) in the
    region of a screenshot."""
    import matplotlib.colors

    hsv = matplotlib.colors.rgb_to_hsv(_screen(png, region))
    vivid = (hsv[..., 1] > 0.45) & (hsv[..., 2] > 0.25)
    out = {}
    for name, hue in MODEL_HUES.items():
        d = np.abs((hsv[..., 0] * 360 - hue + 180) % 360 - 180)
        out[name] = int(np.count_nonzero(vivid & (d < 12)))
    return out


def line_pixels(png: Path, colors: dict[str, tuple[int, int, int]]) -> dict[str, int]:
    """Pixels of each colour (within 20 of 255 per channel) drawn as a thin line on the plots'
    background: with background within 3 pixels on both sides, across or along (legend
    swatches and the interface around the plots have none)."""
    from impactlab.replay.style import PLOT_BACKGROUND

    image = np.round(_screen(png, PLOTS) * 255)
    dark = np.abs(image - PLOT_BACKGROUND).max(axis=-1) <= 10

    def near(axis: int, sign: int) -> np.ndarray:
        return np.any([np.roll(dark, sign * k, axis=axis) for k in (1, 2, 3)], axis=0)

    thin = (near(0, 1) & near(0, -1)) | (near(1, 1) & near(1, -1))
    out = {}
    for name, rgb in colors.items():
        close = np.linalg.norm(image - np.asarray(rgb), axis=-1) < 20
        out[name] = int(np.count_nonzero(close & thin))
    return out


def _serve_folder(folder: Path):
    """An HTTP server of `folder` on a free port (with CORS, for the web viewer), in a thread."""
    import functools
    import http.server
    import threading

    class Handler(http.server.SimpleHTTPRequestHandler):
        def end_headers(self) -> None:
            self.send_header("Access-Control-Allow-Origin", "*")
            super().end_headers()

        def log_message(self, *args: object) -> None:
            pass

    server = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), functools.partial(Handler, directory=str(folder))
    )
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


def serves(url: str) -> bool:
    """Whether a server answers at `url` (a request that fails says no)."""
    import urllib.request

    try:
        urllib.request.urlopen(url, timeout=2).close()
    except OSError:
        return False
    return True


def screenshot_replay(
    rrd: Path,
    png: Path,
    count: Callable[[Path], dict[str, int]],
    *,
    wait_s: float = 240.0,
    enough: int = 150,
) -> dict[str, int]:
    """Open `rrd` in the Rerun viewer (web build, Chromium on Xvfb) and screenshot the screen
    until `count` of the screenshot is `enough` for each of its keys or `wait_s` passes;
    returns the last counts."""
    import os
    import shutil
    import signal
    import subprocess
    import sys
    import time
    import urllib.parse
    import urllib.request

    missing = [t for t in VIEWER_TOOLS if shutil.which(t) is None]
    assert not missing, (
        f"the viewer test needs {', '.join(missing)} (apt: xvfb chromium imagemagick)"
    )
    rerun_exe = Path(sys.executable).with_name("rerun")
    display, web = _free_display(), _free_port()
    env = {**os.environ, "DISPLAY": f":{display}"}
    procs: list[subprocess.Popen] = []
    counts: dict[str, int] = {}
    files = _serve_folder(rrd.parent)

    def start(args: list[str], **kw) -> None:
        out = subprocess.DEVNULL
        procs.append(subprocess.Popen(args, stdout=out, stderr=out, start_new_session=True, **kw))

    try:
        start(["Xvfb", f":{display}", "-screen", "0", f"{SCREEN[0]}x{SCREEN[1]}x24"])
        grpc = _free_port()  # not the default 9876, which another test may hold
        start([str(rerun_exe), "--serve-web", "--web-viewer-port", str(web), "--port", str(grpc)])
        up = lambda: serves(f"http://127.0.0.1:{web}/")  # noqa: E731
        wait_until(up, procs[-1], what="the web viewer", poll_s=0.5)  # fails if rerun ends
        source = f"http://127.0.0.1:{files.server_address[1]}/{rrd.name}"
        url = f"http://127.0.0.1:{web}/?url={urllib.parse.quote(source, safe='')}"
        browser = [
            "chromium",
            "--no-sandbox",
            "--no-first-run",
            f"--user-data-dir={png.parent / 'chromium-profile'}",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            "--ignore-gpu-blocklist",
            "--kiosk",
            "--window-position=0,0",
            f"--window-size={SCREEN[0]},{SCREEN[1]}",
        ]
        start([*browser, url], env=env)
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline:
            time.sleep(5)
            shot = ["import", "-window", "root", str(png)]
            if subprocess.run(shot, env=env, capture_output=True).returncode != 0:
                continue
            counts = count(png)
            if min(counts.values()) >= enough:
                time.sleep(5)  # let it settle, then the picture kept
                subprocess.run(shot, env=env, capture_output=True)
                counts = count(png)
                break
    finally:
        files.shutdown()
        for proc in reversed(procs):
            try:
                os.killpg(proc.pid, signal.SIGTERM)
                proc.wait(timeout=10)
            except ProcessLookupError:
                pass
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
    return counts


@pytest.mark.parametrize("mode", ["L", "LA", "RGB", "RGBA"])
def test_hue_pixels_reads_grey_screenshots_as_well_as_colour_ones(mode, tmp_path):
    """A screenshot of a blank page is written as a grey PNG: no model colour, no error; a
    colour one counts its model colour's pixels."""
    from PIL import Image

    png = tmp_path / f"{mode}.png"
    rgb = np.full((40, 60, 3), 255, np.uint8)
    rgb[5:15, 5:15] = (0, 200, 200)  # cyan: the torso's hue, 100 pixels
    Image.fromarray(rgb).convert(mode).save(png)
    counts = hue_pixels(png, (0.0, 0.05, 0.6, 0.55))
    torso = 100 if mode.startswith("RGB") else 0
    assert counts == {"torso (cyan)": torso, "legs (orange)": 0, "foot (magenta)": 0}


@pytest.mark.slow
def test_the_viewer_draws_the_articulated_model(models, tmp_path):
    """Not an empty or sphere-only view: the torso's, legs' and foot's colours cover pixels
    of the 3D view (a sphere-only replay shows none of those hues)."""
    log, _ = models["walker"]
    rrd = tmp_path / "walker.rrd"
    replay_logs([log], out=rrd, analysis_dir=None)
    png = tmp_path / "walker.png"
    counts = screenshot_replay(rrd, png, lambda shot: hue_pixels(shot, MODEL_VIEW))
    assert counts and min(counts.values()) >= 150, counts


HANDOUT_RUNS = {  # the handout's drop and collision (their body names), short
    "drop": toml(drop("layout_drop", z=0.5, timestep=0.0005, max_time=0.6)),
    "collision": toml(collision("layout_collision", names=("ball1", "ball2"), timestep=0.0005)),
}


@pytest.mark.parametrize("kind", sorted(HANDOUT_RUNS))
def test_foxglove_layout_plots_what_a_handout_log_holds(kind, tmp_path):
    """Every plot path of the shipped layout for drops (collisions) names a channel of a
    handout drop (collision) and a field its messages have, with values that change; every
    plot's legend sits above it (off the data) and its time axis is synced with the others'."""
    import json
    from importlib.resources import files

    layout = json.loads((files("impactlab.replay") / f"foxglove-{kind}.json").read_text())
    spec = tmp_path / f"{kind}.toml"
    spec.write_text(HANDOUT_RUNS[kind])
    (result,) = record_runs(plan([spec]), tmp_path / "logs")
    with open(result.path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        messages = defaultdict(list)
        for _, channel, _, decoded in reader.iter_decoded_messages():
            messages[channel.topic].append(decoded)
    plots = [c for key, c in layout["configById"].items() if key.startswith("Plot!")]
    assert all(c["legendDisplay"] == "top" and c["isSynced"] for c in plots)
    paths = [p["value"] for c in plots for p in c["paths"]]
    assert {p.split(".")[0] for p in paths} >= {"/energy", "/contacts"}
    for path in paths:
        topic, *fields = path.split(".")
        assert topic in messages, path
        values = []
        for msg in messages[topic]:
            value = msg
            for field in fields:
                name, _, index = field.partition("[")
                value = getattr(value, name)
                if index:
                    value = value[int(index.rstrip("]"))]
            values.append(float(value))
        assert np.ptp(values) > 0, path
    panels = layout["configById"]
    assert panels["RosOut!events"]["topicToRender"] in messages
    assert panels["RawMessages!impacts"]["topicPath"] in messages
    assert "/scene" in panels["3D!impactlab"]["topics"]
    shown = json.dumps(layout["layout"])  # every panel configured is placed in the layout
    assert all(f'"{key}"' in shown for key in panels)


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(HANDOUT_RUNS))
def test_the_viewer_shows_every_plotted_series_in_its_colour(kind, tmp_path):
    """A handout drop (collision) replayed and opened in the viewer: every line of the
    recording (its colour read back from the file) shows on the plots as a thin line of that
    colour on their background, at least 100 pixels of it. The screenshot stays in
    `tmp_path` for a person to look at."""
    spec = tmp_path / f"{kind}.toml"
    spec.write_text(HANDOUT_RUNS[kind])
    (result,) = record_runs(plan([spec]), tmp_path / "logs")
    rrd = tmp_path / f"{kind}.rrd"
    replay_logs([result.path], out=rrd, analysis_dir=None)
    lines = {
        path: _unpack(row["SeriesLines:colors"][0])[:3]
        for path, row in _static_chunks(rrd).items()
        if "SeriesLines:colors" in row
    }
    assert len(lines) >= 4
    counts = screenshot_replay(
        rrd, tmp_path / f"{kind}.png", lambda shot: line_pixels(shot, lines), enough=100
    )
    assert counts and min(counts.values()) >= 100, counts


def test_a_damaged_geom_table_loses_only_the_bad_rows():
    """The table is untrusted: a row of the wrong shape, an unknown type, a colour out of
    range or a missing or cut mesh is one problem each; the other rows are kept."""
    import json

    from impactlab.logs.geoms import encode_stl

    good = {
        "name": "a",
        "body": "world",
        "type": "box",
        "size": [1, 1, 1],
        "pos": [0, 0, 0],
        "quat": [1, 0, 0, 0],
        "rgba": [1, 0, 0, 1],
        "group": 0,
        "mesh": None,
    }
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], dtype=float)
    rows = [
        good,
        {**good, "name": "b", "type": "teapot"},
        {**good, "name": "c", "size": [1, "x", 1]},
        {**good, "name": "d", "rgba": [2, 0, 0, 1]},
        {**good, "name": "e", "type": "mesh", "mesh": "meshes/gone.stl"},
        {**good, "name": "f", "type": "mesh", "mesh": "meshes/cut.stl"},
        {**good, "name": "g", "type": "mesh", "mesh": "meshes/ok.stl", "pos": [0, 0, float("nan")]},
        {**good, "name": "h", "type": "mesh", "mesh": "meshes/ok.stl"},
        "not an object",
    ]
    stl = encode_stl(tri)
    scene = read_scene(
        {"geoms": json.dumps(rows)}, {"meshes/ok.stl": stl, "meshes/cut.stl": stl[:-10]}
    )
    assert [g.name for g in scene.geoms] == ["a", "h"]
    assert len(scene.problems) == len(rows) - 2
    np.testing.assert_allclose(scene.meshes["meshes/ok.stl"], tri)
    assert read_scene({"geoms": "{not json"}, {}).problems == ["impactlab.scene geoms: not JSON"]


def test_diff_compares_meshes_within_float32_precision():
    from impactlab.logs.geoms import encode_stl
    from impactlab.tools.compare import EXACT
    from impactlab.tools.diff import compare_attachments

    tri = np.random.default_rng(1).normal(size=(20, 3, 3))
    a = {"meshes/m.stl": encode_stl(tri)}
    rounded = {"meshes/m.stl": encode_stl(tri * (1 + 1e-7))}  # another CPU's last bit
    moved = {"meshes/m.stl": encode_stl(tri + 1e-4)}
    assert rounded["meshes/m.stl"] != a["meshes/m.stl"]
    assert compare_attachments(a, rounded, tolerance=EXACT)[0].equal
    assert not compare_attachments(a, moved, tolerance=EXACT)[0].equal


def test_tf_stamps_of_every_varint_length_decode_as_their_log_time():
    """Seconds and nanoseconds of 0 to 5 varint bytes (proto3 omits zeros), two bodies."""
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms

    from impactlab.logs.messages import stamped_transforms

    parts = [0, 1, 127, 128, 16_383, 16_384, 2_097_152, 268_435_456, 999_999_999]
    seconds = [0, 1, 200, 20_000, 3_000_000, 9_000_000_000]
    t = np.array(sorted(s * 1_000_000_000 + n for s in seconds for n in parts), dtype=np.int64)
    poses = np.random.default_rng(2).normal(size=(t.size, 14))
    seen = np.zeros(t.size, bool)
    for rows, payloads in stamped_transforms(("a", "b"), t, poses):
        for row, payload in zip(rows, payloads, strict=True):
            msg = FrameTransforms.FromString(payload.tobytes())
            assert [x.timestamp.ToNanoseconds() for x in msg.transforms] == [t[row]] * 2
            assert [x.child_frame_id for x in msg.transforms] == ["a", "b"]
            assert msg.transforms[1].rotation.z == poses[row, 13]
            seen[row] = True
    assert seen.all()


def test_a_log_without_a_geom_table_still_shows_its_balls_and_plane(tmp_path):
    """Logs written before the geom table (the golden logs): each ball a sphere of its radius
    and colour, the spec's plane, drawn as the geoms of a table are."""
    log = GOLDEN / "format1" / "drop_restitution.mcap"
    run = load_log(log)
    assert not run.scene  # written before the table
    rrd = tmp_path / "old.rrd"
    replay_logs([log], out=rrd, analysis_dir=None)
    static = _static_chunks(rrd)
    prefix = f"{run_prefix(run.run_id)}/world"
    (ball,) = run.bodies
    sphere = static[f"{prefix}/bodies/{ball}/geoms/{ball}"]
    radius = run.body_info[ball].radius
    np.testing.assert_allclose(sphere["Ellipsoids3D:half_sizes"], [[radius] * 3], rtol=1e-6)
    from impactlab.logs.geoms import BODY_PALETTE

    rgba = run.spec["bodies"][ball].get("rgba") or BODY_PALETTE[0]  # the spec's default
    (color,) = sphere["Ellipsoids3D:colors"]
    _same_color(_unpack(color)[:3], tuple(round(255 * c) for c in rgba[:3]))
    plane = static[f"{prefix}/static/plane"]  # its top at the spec's plane
    assert plane["Transform3D:translation"][0][2] == pytest.approx(run.plane_z)
    assert plane["Boxes3D:centers"][0][2] == pytest.approx(-0.0005)
    assert f"{prefix}/bodies/{ball}/marker" in static
    assert sorted(p for p in static if "/geoms/" in p or "/static/" in p) == [
        f"{prefix}/bodies/{ball}/geoms/{ball}",
        f"{prefix}/static/plane",
    ]
