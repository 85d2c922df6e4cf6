"""Wrong specs, options and models: one line naming file, field, problem; exit 2; no output."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from specs import ball, drop, spec, toml

from impactlab.cli import main

GOOD = toml(drop(max_time=0.01))
COLLIDE = toml(
    spec(
        "c",
        {"a": ball(0.0), "b": ball(0.0, x=1.0)},
        gravity=[0.0, 0.0, 0.0],
        plane=False,
        max_time=0.01,
        separation=0.1,
    )
)
NOTHING_MOVES = '<mujoco><worldbody><geom type="plane" size="1 1 0.1"/></worldbody></mujoco>'
NO_GROUND = '<mujoco><worldbody><body><freejoint/><geom size="0.1"/></body></worldbody></mujoco>'


def edit(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new, 1)


# (case id, spec text or None for the good spec, extra CLI args, words the message must hold)
CASES = [
    ("unknown top key", GOOD + "colour = 1\n", [], ["colour", "unknown key"]),
    ("unknown option", edit(GOOD, "timestep", "tmestep"), [], ["options.tmestep", "unknown"]),
    ("unknown body key", edit(GOOD, "mass =", "weight ="), [], ["bodies.ball.weight"]),
    ("negative radius", edit(GOOD, "radius = 0.1", "radius = -0.1"), [], ["radius", "> 0"]),
    ("zero mass", edit(GOOD, "mass = 1.0", "mass = 0.0"), [], ["bodies.ball.mass", "> 0"]),
    ("radius is text", edit(GOOD, "radius = 0.1", 'radius = "big"'), [], ["radius", "number"]),
    ("zero timestep", edit(GOOD, "timestep = 0.001", "timestep = 0.0"), [], ["timestep", "> 0"]),
    ("negative timestep", edit(GOOD, "0.001", "-0.001"), [], ["options.timestep"]),
    ("nan timestep", edit(GOOD, "0.001", "nan"), [], ["options.timestep", "finite"]),
    (
        "bad integrator",
        GOOD.replace("[options]", '[options]\nintegrator = "Verlet"'),
        [],
        ["integrator"],
    ),
    (
        "gravity length",
        GOOD.replace("[options]", "[options]\ngravity = [0, -9.81]"),
        [],
        ["gravity", "3"],
    ),
    (
        "pos length",
        edit(GOOD, "pos = [0.0, 0.0, 1.0]", "pos = [0.0, 1.0]"),
        [],
        ["bodies.ball.pos"],
    ),
    ("missing pos", edit(GOOD, "pos = [0.0, 0.0, 1.0]", ""), [], ["bodies.ball.pos", "required"]),
    ("missing max_time", edit(GOOD, "max_time = 0.01", ""), [], ["stop.max_time", "required"]),
    ("no bodies", GOOD.split("[bodies.ball]")[0] + "[stop]\nmax_time = 1.0\n", [], ["bodies"]),
    (
        "body below plane",
        edit(GOOD, "pos = [0.0, 0.0, 1.0]", "pos = [0.0, 0.0, 0.05]"),
        [],
        ["below the plane"],
    ),
    ("bad condim", GOOD + "[contact]\ncondim = 2\n", [], ["contact.condim"]),
    ("bad solimp", GOOD + "[contact]\nsolimp = [1.5, 0.95, 0.001]\n", [], ["contact.solimp"]),
    ("bad solref", GOOD + "[contact]\nsolref = [0.02, -1.0]\n", [], ["contact.solref"]),
    ("bad rgba", edit(GOOD, "mass = 1.0", "mass = 1.0\nrgba = [2, 0, 0, 1]"), [], ["rgba", "<= 1"]),
    ("log every zero", GOOD + "[logging]\nevery = 0\n", [], ["logging.every", ">= 1"]),
    (
        "bounces without plane",
        GOOD + "[plane]\nenabled = false\n",
        ["--set", "stop.bounces=2"],
        ["stop.bounces", "plane"],
    ),
    ("bounces and separation", COLLIDE + "bounces = 2\n", [], ["stop", "either"]),
    (
        "separation one body",
        GOOD.replace("max_time = 0.01", "max_time = 0.01\nseparation = 0.1"),
        [],
        ["separation", "two bodies"],
    ),
    (
        "rest_time too long",
        GOOD.replace("max_time = 0.01", "max_time = 0.01\nat_rest = true\nrest_time = 1.0"),
        [],
        ["rest_time"],
    ),
    (
        "timestep exceeds limit",
        edit(GOOD, "max_time = 0.01", "max_time = 0.0005"),
        [],
        ["options.timestep", "max_time"],
    ),
    (
        "empty sweep",
        GOOD + '[sweep]\n"ball.mass" = []\n',
        [],
        ["sweep.bodies.ball.mass", "non-empty"],
    ),
    (
        "sweep unknown field",
        GOOD + '[sweep]\n"ball.colour" = [1, 2]\n',
        [],
        ["ball.colour", "unknown field"],
    ),
    (
        "sweep bad value",
        GOOD + '[sweep]\n"ball.mass" = [1.0, -2.0]\n',
        [],
        ["bodies.ball.mass", "> 0"],
    ),
    ("sweep not a list", GOOD + '[sweep]\n"ball.mass" = 2.0\n', [], ["sweep", "list"]),
    ("invalid toml", "name = = 1\n", [], ["invalid TOML"]),
    ("set unknown field", GOOD, ["--set", "ball.colour=1"], ["ball.colour", "unknown field"]),
    ("set without value", GOOD, ["--set", "ball.mass"], ["PATH=VALUE"]),
    ("set bad value", GOOD, ["--set", "ball.mass=-1"], ["bodies.ball.mass", "> 0"]),
    ("duration on a spec", GOOD, ["--duration", "1"], ["--duration", "MJCF"]),
]


@pytest.mark.slow
@pytest.mark.parametrize(("case", "text", "args", "words"), CASES, ids=[c[0] for c in CASES])
def test_bad_spec(tmp_path, capsys, case, text, args, words):
    spec = tmp_path / "spec.toml"
    spec.write_text(text)
    out = tmp_path / "out"
    code = main(["record", str(spec), "-o", str(out), *args])
    assert_one_line_error(capsys, code, words, out)


def assert_one_line_error(capsys, code: int, words: list[str], out: Path) -> None:
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("impactlab: error: ")
    for word in words:
        assert word in lines[0], (word, lines[0])
    assert "Traceback" not in err
    assert not out.exists() or not os.listdir(out)


@pytest.mark.parametrize(
    ("case", "content", "args", "words"),
    [
        (
            "malformed mjcf",
            "<mujoco><worldbody><body>",
            ["--duration", "1"],
            ["model.xml", "invalid MJCF"],
        ),
        ("no duration", NOTHING_MOVES, [], ["--duration"]),
        ("set on mjcf", NOTHING_MOVES, ["--duration", "1", "--set", "a=1"], ["--set"]),
        (
            "mjcf bad option",
            NO_GROUND,
            ["--duration", "1", "--set", "logging.every=0"],
            ["logging.every", ">= 1"],
        ),
        (
            "mjcf two limits",
            NO_GROUND,
            ["--duration", "1", "--set", "stop.max_time=2"],
            ["--duration", "not both"],
        ),
        (
            "mjcf bounces, no ground",
            NO_GROUND,
            ["--duration", "1", "--set", "stop.bounces=2"],
            ["stop.bounces", "ground"],
        ),
        (
            "mjcf collision, one body",
            NO_GROUND,
            ["--duration", "1", "--set", "stop.separation=0.1"],
            ["stop.separation", "two free bodies"],
        ),
        (
            "mjcf rest_time too long",
            NO_GROUND,
            ["--duration", "1", "--set", "stop.at_rest=true", "--set", "stop.rest_time=2"],
            ["stop.rest_time", "not shorter than stop.max_time = 1"],
        ),
        (
            "mjcf bounces and separation",
            NO_GROUND,
            ["--duration", "1", "--set", "stop.bounces=1", "--set", "stop.separation=0.1"],
            ["stop: give either bounces"],
        ),
    ],
)
def test_bad_mjcf(tmp_path, capsys, case, content, args, words):
    model = tmp_path / "model.xml"
    model.write_text(content)
    out = tmp_path / "out"
    code = main(["record", str(model), "-o", str(out), *args])
    assert_one_line_error(capsys, code, words, out)


def test_missing_and_unknown_inputs(tmp_path, capsys):
    out = tmp_path / "out"
    assert_one_line_error(
        capsys,
        main(["record", str(tmp_path / "nope.toml"), "-o", str(out)]),
        ["nope.toml", "not found"],
        out,
    )
    other = tmp_path / "notes.txt"
    other.write_text("x")
    assert_one_line_error(
        capsys, main(["record", str(other), "-o", str(out)]), ["notes.txt", ".toml"], out
    )


def test_a_bad_spec_among_good_ones_writes_nothing(tmp_path, capsys):
    good, bad = tmp_path / "good.toml", tmp_path / "bad.toml"
    good.write_text(GOOD)
    bad.write_text(edit(GOOD, "radius = 0.1", "radius = -1.0"))
    out = tmp_path / "out"
    assert_one_line_error(
        capsys, main(["record", str(good), str(bad), "-o", str(out)]), ["bad.toml"], out
    )


def test_unwritable_output_fails_before_simulating(tmp_path, capsys):
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD)
    target = Path("/proc/impactlab-cannot-write-here")  # not writable, even for root
    code = main(["record", str(spec), "-o", str(target)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "cannot write" in err[0]


def test_output_path_that_is_a_file(tmp_path, capsys):
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD)
    blocker = tmp_path / "file"
    blocker.write_text("")
    code = main(["record", str(spec), "-o", str(blocker)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "cannot write" in err[0]
