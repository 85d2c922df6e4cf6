"""Valid but unusual models, specs and options (issue 25): each is handled or one error line.

Model rewriting never writes over the model's own files and keeps their bytes; a log carries
what reproduces its run and is reused only when every file of the model is unchanged; the
names impactlab generates cannot clash with the user's; the rest are one line, exit 2.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest
import zstandard
from specs import drop, toml

from impactlab.cli import main

BALL = """<mujoco>
  <worldbody>
    <body name="ball" pos="0 0 0.5">
      <freejoint/>
      <geom name="g" type="sphere" size="0.1" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""
MAIN = """<mujoco model="m">
  <option timestep="{dt}"/>
  <include file="ball.xml"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
  </worldbody>
</mujoco>
"""
ONE = """<mujoco model="m">
  <option timestep="0.00002"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="{body}" pos="0 0 0.5">
      <freejoint/>
      <geom name="a" type="sphere" size="0.1" mass="1"/>
    </body>
  </worldbody>
  <contact>
    <pair geom1="a" geom2="floor"/>
  </contact>
</mujoco>
"""


def cli(capsys, *args: str) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def one_error(err: str, *words: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("impactlab"), err
    for word in words:
        assert word in lines[0], err


def digest(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


@pytest.fixture
def included(tmp_path) -> Path:
    (tmp_path / "ball.xml").write_text(BALL)
    (tmp_path / "main.xml").write_text(MAIN.format(dt="0.00002"))
    return tmp_path


# -- rewriting a user's model ------------------------------------------------------------


def test_contact_never_writes_over_an_included_file(included, capsys):
    before = digest(included)
    code, _, err = cli(
        capsys,
        "contact",
        included / "main.xml",
        "--pair",
        "g/floor=0.8",
        "-o",
        included / "ball.xml",
    )
    assert code == 2
    one_error(err, "ball.xml", "-o")
    (included / "link.xml").symlink_to(included / "ball.xml")
    code, _, err = cli(
        capsys,
        "contact",
        included / "main.xml",
        "--pair",
        "g/floor=0.8",
        "-o",
        included / "link.xml",
    )
    assert code == 2
    one_error(err, "link.xml")
    code, _, err = cli(
        capsys,
        "contact",
        included / "main.xml",
        "--pair",
        "g/floor=0.8",
        "-o",
        included / "main.xml",
    )
    assert code == 2
    one_error(err, "main.xml")
    after = digest(included)
    after.pop("link.xml")
    assert after == before


def test_contact_with_an_include_writes_a_model_that_compiles(included, capsys):
    out = included / "tuned.xml"
    code, _, err = cli(capsys, "contact", included / "main.xml", "--pair", "g/floor=0.8", "-o", out)
    assert code == 0, err
    model = mujoco.MjModel.from_xml_path(str(out))
    assert model.npair == 1
    assert (included / "ball.xml").read_text() == BALL


def test_a_pair_given_twice_is_refused(tmp_path, capsys):
    path = tmp_path / "m.xml"
    path.write_text(ONE.format(body="a"))
    out = tmp_path / "out.xml"
    code, _, err = cli(
        capsys, "contact", path, "--pair", "a/floor=0.8", "--pair", "floor/a=0.8", "-o", out
    )
    assert code == 2
    one_error(err, "a/floor", "floor/a")
    assert not out.exists()


@pytest.mark.slow
def test_line_ends_and_encoding_are_kept(tmp_path, capsys):
    text = '<?xml version="1.0" encoding="ISO-8859-1"?>\n<!-- café au lait -->\n'
    text += ONE.format(body="b")
    raw = text.replace("\n", "\r\n").encode("iso-8859-1")
    path = tmp_path / "latin.xml"
    path.write_bytes(raw)
    out = tmp_path / "out.xml"
    code, _, err = cli(capsys, "contact", path, "--pair", "a/floor=0.8", "-o", out)
    assert code == 0, err
    written = out.read_bytes()
    assert b"caf\xe9 au lait" in written  # still ISO-8859-1
    assert written.count(b"\n") == written.count(b"\r\n")  # every line end CRLF
    assert written.count(b"\r\n") == raw.count(b"\r\n")  # the pair replaced in place
    assert mujoco.MjModel.from_xml_path(str(out)).npair == 1
    # record reads it too, and its log keeps the text as UTF-8, declared so, line ends kept
    code, _, err = cli(capsys, "record", path, "--duration", "0.001", "-o", tmp_path / "logs")
    assert code == 0, err
    (log,) = tmp_path.glob("logs/*.mcap")
    kept = attachments(log)["model.xml"]
    assert kept.decode("utf-8") == text.replace("\n", "\r\n").replace("ISO-8859-1", "UTF-8")


def test_a_name_that_is_not_utf8_is_one_line(tmp_path, capsys):
    text = '<?xml version="1.0" encoding="ISO-8859-1"?>\n' + ONE.format(body="café")
    path = tmp_path / "latin.xml"
    path.write_bytes(text.encode("iso-8859-1"))
    code, _, err = cli(capsys, "contact", path, "--pair", "a/floor=0.8")
    assert code == 2
    one_error(err, "UTF-8")
    code, _, err = cli(capsys, "record", path, "--duration", "0.001", "-o", tmp_path / "logs")
    assert code == 2
    one_error(err, "UTF-8")
    assert not (tmp_path / "logs").exists()


# -- logs that reproduce their run ------------------------------------------------------

MESH = """<mujoco model="mesh">
  <option timestep="0.001"/>
  <asset><mesh name="tet" file="tet.obj"/></asset>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="rock" pos="0 0 0.5">
      <freejoint/>
      <geom name="rock" type="mesh" mesh="tet" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""
TET = "v 0 0 0\nv {s} 0 0\nv 0 {s} 0\nv 0 0 {s}\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def record(capsys, model: Path, out: Path) -> tuple[str, list[Path]]:
    code, printed, err = cli(capsys, "record", model, "--duration", "0.005", "-o", out)
    assert code == 0, err
    return printed, sorted(out.glob("*.mcap"))


def attachments(log: Path) -> dict[str, bytes]:
    from impactlab.logs.reader import read_attachments

    return dict(read_attachments(log))


def test_a_log_of_a_model_with_includes_compiles_alone_and_is_not_reused_stale(included, capsys):
    (included / "main.xml").write_text(MAIN.format(dt="0.001"))
    printed, logs = record(capsys, included / "main.xml", included / "logs")
    assert len(logs) == 1
    xml = attachments(logs[0])["model.xml"].decode()
    assert "<include" not in xml
    alone = mujoco.MjModel.from_xml_string(xml)  # no file beside it
    assert alone.nbody == 2 and alone.body_pos[1][2] == pytest.approx(0.5, abs=1e-15)
    (included / "ball.xml").write_text(BALL.replace("0 0 0.5", "0 0 0.625"))
    printed, logs = record(capsys, included / "main.xml", included / "logs")
    assert "reused" not in printed
    assert len(logs) == 2  # the edit is another run
    heights = sorted(
        mujoco.MjModel.from_xml_string(attachments(p)["model.xml"].decode()).body_pos[1][2]
        for p in logs
    )
    assert heights == pytest.approx([0.5, 0.625], abs=1e-15)
    printed, again = record(capsys, included / "main.xml", included / "logs")
    assert "reused 1" in printed and again == logs  # unchanged files: reused
    (included / "ball.xml").write_text(BALL.replace("0 0 0.5", "0 0 0.625") + "<!-- x -->\n")
    printed, _ = record(capsys, included / "main.xml", included / "logs")
    assert "reused 1" in printed  # the key is the model MuJoCo compiles: a comment is none


def test_a_log_of_a_model_with_a_mesh_carries_the_compiled_model(tmp_path, capsys):
    (tmp_path / "m.xml").write_text(MESH)
    (tmp_path / "tet.obj").write_text(TET.format(s=0.2))
    _, logs = record(capsys, tmp_path / "m.xml", tmp_path / "logs")
    binary = tmp_path / "model.mjb"  # as `zstd -d model.mjb.zst` writes it
    binary.write_bytes(zstandard.decompress(attachments(logs[0])["model.mjb.zst"]))
    model = mujoco.MjModel.from_binary_path(str(binary))
    source = mujoco.MjModel.from_xml_path(str(tmp_path / "m.xml"))
    assert model.nmeshvert == source.nmeshvert
    assert model.mesh_vert == pytest.approx(source.mesh_vert, abs=1e-12)
    mesh = (tmp_path / "tet.obj").read_bytes()
    code, _, err = cli(
        capsys, "contact", tmp_path / "m.xml", "--pair", "rock/floor=0.8", "--speed", "1",
        "--max-penetration", "0.001", "-o", tmp_path / "tet.obj",
    )  # fmt: skip
    assert code == 2
    one_error(err, "tet.obj")
    assert (tmp_path / "tet.obj").read_bytes() == mesh
    (tmp_path / "tet.obj").write_text(TET.format(s=0.3))  # the mesh changes, the XML does not
    printed, logs = record(capsys, tmp_path / "m.xml", tmp_path / "logs")
    assert "reused" not in printed and len(logs) == 2


def test_a_nan_in_a_model_is_one_line_and_writes_nothing(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "m.xml").write_text(MESH.replace('pos="0 0 0.5"', 'pos="0 0 nan"'))
    (tmp_path / "tet.obj").write_text(TET.format(s=0.2))
    code, _, err = cli(capsys, "record", "m.xml", "--duration", "0.01", "-o", "logs")
    assert code == 2
    one_error(err, "m.xml", "NaN")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.xml", "tet.obj"]
    code, _, err = cli(capsys, "contact", "m.xml", "--pair", "rock/floor=0.8", "--speed", "1")
    assert code == 2
    one_error(err, "m.xml", "NaN")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.xml", "tet.obj"]


# -- generated names cannot clash with the user's ----------------------------------------

NAMES = {
    "unnamed body beside body2": """<mujoco><option timestep="0.001"/><worldbody>
  <geom name="floor" type="plane" size="5 5 0.1"/>
  <body name="body2" pos="0 0 1"><freejoint/><geom name="x" size="0.1"/></body>
  <body pos="1 0 1"><freejoint/><geom name="y" size="0.1"/></body></worldbody></mujoco>""",
    "unnamed geom beside geom1": """<mujoco><option timestep="0.001"/><worldbody>
  <geom name="geom1" type="plane" size="5 5 0.1"/>
  <body name="b" pos="0 0 1"><freejoint/><geom size="0.1"/></body></worldbody></mujoco>""",
    "geom names with colons": """<mujoco><option timestep="0.001"/><worldbody>
  <geom name="a:b" type="plane" size="5 5 0.1"/>
  <geom name="a" type="plane" pos="0 0 -0.5" size="5 5 0.1"/>
  <body name="b" pos="0 0 1"><freejoint/><geom name="b:c" size="0.1"/>
    <geom name="c" size="0.1" pos="0.1 0 0"/></body></worldbody></mujoco>""",
    "the user's own impactlab: sensor": """<mujoco><option timestep="0.001"/><worldbody>
  <geom name="floor" type="plane" size="5 5 0.1"/>
  <body name="b" pos="0 0 1"><freejoint/><geom name="g" size="0.1"/></body></worldbody>
  <sensor><framepos name="impactlab:e_potential" objtype="body" objname="b"/>
    <framepos name="impactlab2:b:framepos" objtype="body" objname="b"/></sensor></mujoco>""",
}


@pytest.mark.slow
@pytest.mark.parametrize("case", list(NAMES))
def test_generated_names_do_not_clash(case, tmp_path, capsys):
    from impactlab.logs.load import load_log

    (tmp_path / "m.xml").write_text(NAMES[case])
    _, logs = record(capsys, tmp_path / "m.xml", tmp_path / "logs")
    log = load_log(logs[0])
    assert not log.partial
    assert len(log.bodies) == NAMES[case].count("<body")
    for frame in log.bodies.values():  # each fell freely from z = 1 for 5 ms (Euler)
        n = np.rint(frame["t_s"].to_numpy() / 0.001)
        assert frame["z"].to_numpy() == pytest.approx(1 - 9.81e-6 * n * (n + 1) / 2, abs=1e-9)
    code, _, err = cli(capsys, "analyze", logs[0], "-o", tmp_path / "out")
    assert code == 0, err


# -- specs: names and sweeps that are valid ----------------------------------------------


def small(body: str = "ball", **options) -> str:
    """One ball named `body` 0.5 m up, 0.02 s of it, as TOML."""
    return toml(drop("s", z=0.5, body=body, **{"max_time": 0.02, **options}))


@pytest.mark.slow
def test_a_sweep_over_the_description_is_analyzed(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(small(sweep={"description": ["first", "second"]}))
    code, _, err = cli(capsys, "record", spec, "-o", tmp_path / "logs")
    assert code == 0, err
    code, _, err = cli(capsys, "analyze", tmp_path / "logs", "-o", tmp_path / "out", "--no-figures")
    assert code == 0, err
    import polars as pl

    runs = pl.read_parquet(tmp_path / "out" / "runs.parquet")
    assert sorted(runs["description"].to_list()) == ["first", "second"]


@pytest.mark.parametrize("name", ["plane", "world"])
def test_a_body_named_like_the_plane_or_the_world_is_one_line(name, tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(small(name))
    code, _, err = cli(capsys, "record", spec, "-o", tmp_path / "logs")
    assert code == 2
    one_error(err, "s.toml", f"bodies.{name}")
    assert not (tmp_path / "logs").exists()


@pytest.mark.slow
def test_a_body_named_total_keeps_its_energy_rows(tmp_path, capsys):
    import polars as pl

    spec = tmp_path / "s.toml"
    spec.write_text(small("total"))
    assert cli(capsys, "record", spec, "-o", tmp_path / "logs")[0] == 0
    code, _, err = cli(capsys, "analyze", tmp_path / "logs", "-o", tmp_path / "out")
    assert code == 0, err
    energy = pl.read_parquet(tmp_path / "out" / "energy.parquet")
    body = energy.filter(~pl.col("is_total"))
    total = energy.filter(pl.col("is_total"))
    assert body["body"].unique().to_list() == ["total"] == total["body"].unique().to_list()
    assert body.height == total.height == 21
    assert energy["is_total"].to_list() == [True] * 21 + [False] * 21  # "total" sorts first
    # one body: the sum is the body's own energy, and the body's rows carry its height
    assert body["total_J"].to_numpy() == pytest.approx(total["total_J"].to_numpy(), abs=1e-12)
    assert body["height_m"].null_count() == 0 and total["height_m"].null_count() == 21


# -- options ---------------------------------------------------------------------------


def test_a_line_break_in_a_set_value_is_one_line(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(small())
    code, _, err = cli(
        capsys, "record", spec, "-o", tmp_path / "logs", "--set", "ball.mass=2\nball.radius=0.05"
    )
    assert code == 2
    one_error(err, "--set", "line break")
    assert not (tmp_path / "logs").exists()


def test_calibrate_with_a_target_twice_is_one_line_and_leaves_nothing(
    tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    code, _, err = cli(capsys, "calibrate", "--targets", "0.8", "0.8", "-o", "out")
    assert code == 2
    one_error(err, "--targets", "0.8")
    assert list(tmp_path.iterdir()) == []


def test_diff_in_the_python_api(tmp_path, capsys):
    import impactlab

    spec = tmp_path / "s.toml"
    spec.write_text(small())
    assert cli(capsys, "record", spec, "-o", tmp_path / "a")[0] == 0
    assert cli(capsys, "record", spec, "-o", tmp_path / "b", "--set", "ball.mass=2")[0] == 0
    (a,), (b,) = sorted((tmp_path / "a").glob("*.mcap")), sorted((tmp_path / "b").glob("*.mcap"))
    assert impactlab.diff(a, a).equal
    assert not impactlab.diff(a, b).equal


# -- advice that is accepted when followed -----------------------------------------------

BOUND = re.compile(r"timestep <= ([0-9.e+-]+) s")


@pytest.mark.slow
def test_the_timestep_a_refusal_names_is_accepted_as_printed(tmp_path, capsys):
    args = ["contact", "--restitution", "0.3", "--radius", "0.12", "--speed", "0.5..6"]
    code, out, _ = cli(capsys, *args, "--timestep", "1e-5")
    assert code == 1
    printed = BOUND.search(out).group(1)
    assert float(printed) < 2.86e-06  # the bound of the design at 1e-5 is not enough
    code, out, err = cli(capsys, *args, "--timestep", printed)
    assert code == 0, out + err
    # the same in a spec: the refusal's number, used as printed, is accepted
    spec = tmp_path / "r.toml"
    spec.write_text(
        small(
            timestep=1e-5, max_time=0.0005, contact={"restitution": 0.3, "speed_range": [0.5, 6.0]}
        )
    )
    spec.write_text(spec.read_text().replace("radius = 0.1", "radius = 0.12"))
    code, _, err = cli(capsys, "record", spec, "-o", tmp_path / "logs")
    assert code == 2
    one_error(err, "contact")
    printed = BOUND.search(err).group(1)
    code, _, err = cli(
        capsys, "record", spec, "-o", tmp_path / "logs", "--set", f"options.timestep={printed}"
    )
    assert code == 0, err
