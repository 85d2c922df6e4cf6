"""Every command, given a missing or wrong input: exit 2, one line naming it, nothing created;
misspelt keys, tables and `--set` paths get a "did you mean"; a closed pipe or a full stream
is no traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from specs import drop, toml

from impactlab.cli import main

SPEC = toml(drop(max_time=0.05))

# (case, command line); in a folder holding good.mcap, spec.toml, empty/ and afile
CASES = [
    ("record a missing spec", ["record", "nosuch.toml", "-o", "out"]),
    ("record a log", ["record", "good.mcap", "-o", "out"]),
    ("analyze a missing folder", ["analyze", "nosuch/", "-o", "r2"]),
    ("analyze a spec", ["analyze", "spec.toml", "-o", "r3"]),
    ("analyze two missing logs", ["analyze", "nosuch.mcap", "nosuch2.mcap", "-o", "r4"]),
    ("analyze a folder without logs", ["analyze", "empty", "-o", "r5"]),
    ("analyze a pattern matching nothing", ["analyze", "*.nothing", "-o", "r6"]),
    ("analyze a device", ["analyze", "/dev/null", "-o", "r7"]),
    ("replay a missing log", ["replay", "nosuch.mcap"]),
    ("replay a spec", ["replay", "spec.toml", "-o", "x.rrd"]),
    ("replay a folder without logs", ["replay", "empty", "-o", "x.rrd"]),
    ("info a missing log", ["info", "nosuch.mcap"]),
    ("info a spec", ["info", "spec.toml"]),
    ("info a folder", ["info", "empty"]),
    ("diff a missing log", ["diff", "nosuch.mcap", "good.mcap"]),
    ("diff a spec", ["diff", "good.mcap", "spec.toml"]),
    ("diff a folder", ["diff", "good.mcap", "empty"]),
    ("lab a missing folder", ["lab", "--experiments", "nosuch", "-o", "lab"]),
    ("lab an empty folder", ["lab", "--experiments", "empty", "-o", "lab"]),
    ("contact a missing model", ["contact", "nosuch.xml", "--pair", "a/b=0.5", "-o", "t.xml"]),
    (
        "contact an absurd target",
        ["contact", "--restitution", "2", "--speed", "1", "--timestep", "0.001"],
    ),
    ("calibrate an absurd target", ["calibrate", "--targets", "2", "-o", "cal"]),
    ("examples into a file", ["examples", "afile"]),
    ("an unknown option", ["analyze", "good.mcap", "--colour"]),
]


@pytest.fixture
def folder(tmp_path, monkeypatch, record_spec) -> Path:
    (log,) = record_spec("exit_codes", SPEC)
    (tmp_path / "good.mcap").write_bytes(log.read_bytes())
    (tmp_path / "spec.toml").write_text(SPEC)
    (tmp_path / "empty").mkdir()
    (tmp_path / "afile").write_text("")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _tree(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize(("case", "argv"), CASES, ids=[c[0] for c in CASES])
def test_a_wrong_input_is_exit_2_one_line_and_nothing_created(folder, capsys, case, argv):
    before = _tree(folder)
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own mistakes
        code = exc.code
    out, err = capsys.readouterr()
    assert code == 2, (out, err)
    (line,) = err.splitlines()
    assert line.startswith("impactlab: error: ") and "Traceback" not in err
    assert out == ""
    assert _tree(folder) == before


def test_the_wrong_input_is_named(folder, capsys):
    for argv, words in [
        (["analyze", "nosuch/", "-o", "r2"], ["nosuch", "file not found"]),
        (["analyze", "spec.toml"], ["spec.toml", "not an MCAP file", "impactlab record"]),
        (["replay", "nosuch.mcap"], ["nosuch.mcap", "file not found"]),
        (["analyze", "empty"], ["empty", "a folder without .mcap logs"]),
        (["info", "/dev/null"], ["/dev/null", "not a regular file"]),
    ]:
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert all(word in err for word in words), (words, err)


@pytest.mark.parametrize(
    "argv",
    [
        pytest.param(  # the analysis's workers start: about 3 s
            ["analyze", "good.mcap", "nosuch.mcap", "spec.toml", "empty", "-o", "r"],
            marks=pytest.mark.slow,
        ),
        ["replay", "good.mcap", "nosuch.mcap", "spec.toml", "empty", "-o", "r"],
        ["info", "good.mcap", "nosuch.mcap", "spec.toml", "empty"],
    ],
    ids=["analyze", "replay", "info"],
)
def test_bad_inputs_among_good_ones_are_one_line_each_and_the_rest_is_done(folder, capsys, argv):
    assert main(argv) == 1
    out, err = capsys.readouterr()
    errors = [line for line in err.splitlines() if line.startswith("impactlab: error: ")]
    assert sorted(e.split(": ")[2] for e in errors) == ["empty", "nosuch.mcap", "spec.toml"], err
    assert "Traceback" not in err
    if argv[0] == "info":  # the check of `impactlab analyze`'s inputs, with its hint
        (spec,) = [e for e in errors if "spec.toml" in e]
        assert spec.endswith(
            "not an MCAP file (bad magic bytes); `impactlab record` records a spec or model"
        ), spec
    done = {"analyze": "r/runs.parquet", "replay": "r/good.rrd", "info": None}[argv[0]]
    assert (folder / done).is_file() if done else "file:" in out


@pytest.mark.parametrize(
    ("change", "overrides", "expected"),
    [
        (("[stop]", "[stpo]"), [], "stpo: unknown key, did you mean 'stop'?"),
        (
            ("[stop]", '[swep]\n"ball.mass" = [1.0]\n[stop]'),
            [],
            "swep: unknown key, did you mean 'sweep'?",
        ),
        (("timestep", "timestpe"), [], "options.timestpe: unknown key, did you mean 'timestep'?"),
        (("mass =", "mas ="), [], "bodies.ball.mas: unknown key, did you mean 'mass'?"),
        (None, ["bal.mass=2"], "unknown field 'bal.mass', did you mean 'ball.mass'?"),
        (None, ["stop.max_tme=2"], "did you mean 'stop.max_time'?"),
        (None, ["bodies.bal.mass=2"], "unknown body 'bal', did you mean 'ball'? (known: ball)"),
        (("[stop]", '[sweep]\n"bal.mass" = [1.0, 2.0]\n\n[stop]'), [], "did you mean 'ball.mass'?"),
    ],
)
def test_a_misspelt_name_gets_the_closest_known_one(tmp_path, capsys, change, overrides, expected):
    text = SPEC if change is None else SPEC.replace(*change, 1)
    assert change is None or text != SPEC
    spec = tmp_path / "spec.toml"
    spec.write_text(text)
    argv = ["record", str(spec), "-o", str(tmp_path / "out")]
    assert main([*argv, *(a for o in overrides for a in ("--set", o))]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert expected in line
    assert not (tmp_path / "out").exists()


def test_the_known_tables_include_sweep(tmp_path, capsys):
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC + "[colour]\nred = 1\n")
    assert main(["record", str(spec)]) == 2
    err = capsys.readouterr().err
    assert "colour: unknown key (known: " in err and ", sweep)" in err
    assert "did you mean" not in err  # nothing close


def test_a_name_far_from_every_known_one_gets_no_guess(tmp_path, capsys):
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    assert main(["record", str(spec), "--set", "zzz.qqq=1"]) == 2
    assert capsys.readouterr().err.strip().endswith("unknown field 'zzz.qqq'")


# -- closed pipes and full streams: the real program, its stdout a pipe or /dev/full --------


def _program(args: list[str], **kwargs) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "impactlab", *args], **kwargs)


@pytest.fixture(scope="module")
def two_logs(record_spec) -> list[str]:
    logs = record_spec("exit_codes_pair", toml(drop(max_time=0.3, sweep={"ball.mass": [1.0, 2.0]})))
    return [str(p) for p in logs]


SLOW = pytest.mark.slow  # a whole program that reads logs: over a second each


@pytest.mark.parametrize(
    "command", [pytest.param("diff", marks=SLOW), pytest.param("info", marks=SLOW), "help"]
)
def test_a_pipe_closed_before_any_output_ends_the_command_silently(two_logs, command):
    argv = {"diff": ["diff", *two_logs], "info": ["info", *two_logs], "help": ["--help"]}
    read = subprocess.Popen(["true"], stdin=subprocess.PIPE)  # `impactlab ... | true`
    read.wait()  # gone before the command writes a byte
    proc = _program(argv[command], stdout=read.stdin, stderr=subprocess.PIPE)
    read.stdin.close()
    _, err = proc.communicate(timeout=120)
    assert err.decode() == ""  # no traceback, no "Exception ignored"
    assert proc.returncode == 141  # 128 + SIGPIPE, what a shell reports for coreutils


@SLOW
def test_a_pipe_closed_midway_ends_the_command_silently(two_logs, tmp_path):
    """`impactlab info LOGS | head -c 10`: far more than a pipe holds (64 KiB) is written (600
    logs of their own names: a name given twice is described once)."""
    names = [tmp_path / f"log{i}.mcap" for i in range(600)]
    for i, name in enumerate(names):
        os.link(two_logs[i % 2], name)
    read = subprocess.Popen(["head", "-c", "10"], stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    proc = _program(["info", *map(str, names)], stdout=read.stdin, stderr=subprocess.PIPE)
    read.stdin.close()
    _, err = proc.communicate(timeout=120)
    assert len(read.stdout.read()) == 10
    read.wait(timeout=120)
    assert err.decode() == ""
    assert proc.returncode == 141


@pytest.mark.parametrize(
    "command",
    [pytest.param("diff", marks=SLOW), pytest.param("info", marks=SLOW), "help", "version"],
)
def test_a_full_stream_is_one_line_and_exit_2(two_logs, command):
    argv = {
        "diff": ["diff", *two_logs],
        "info": ["info", *two_logs],
        "help": ["--help"],
        "version": ["--version"],
    }
    with open("/dev/full", "w") as full:
        proc = _program(argv[command], stdout=full, stderr=subprocess.PIPE)
        _, err = proc.communicate(timeout=120)
    assert err.decode().splitlines() == [
        "impactlab: error: standard output: cannot write: No space left on device"
    ]
    assert proc.returncode == 2


def test_a_full_stderr_is_silent_with_the_error_code(tmp_path):
    with open("/dev/full", "w") as full:
        proc = _program(["info", str(tmp_path / "nosuch.mcap")], stderr=full)
        proc.wait(timeout=120)
    assert proc.returncode == 2


def test_a_closed_pipe_elsewhere_is_not_taken_for_stdout(monkeypatch, capsys):
    """A BrokenPipeError that is not a write to stdout (a worker's pipe, say) stays a bug."""
    from impactlab import cli

    def broken(args):
        raise BrokenPipeError("a worker's pipe")

    monkeypatch.setenv("MUJOCO_GL", "disable")  # command() sets them if unset
    monkeypatch.setenv("PYDANTIC_DISABLE_PLUGINS", "__all__")
    monkeypatch.setattr(cli, "main", lambda argv=None: broken(argv))
    with pytest.raises(BrokenPipeError):
        cli.command()


def test_the_lab_calibrates_when_asked_and_analyzes_as_analyze_does():
    from impactlab.cli import build_parser

    parser = build_parser()
    assert parser.parse_args(["calibrate"]).targets is None
    assert not parser.parse_args(["lab"]).calibration
    assert parser.parse_args(["lab", "--calibration"]).calibration
    lab, analyze = parser.parse_args(["lab"]), parser.parse_args(["analyze", "x"])
    assert lab.executor == analyze.executor == "processes"
