"""A name is a name: the command line takes file names as written, patterns only when no such
file exists, and a name that is not UTF-8 text (where tables, reports or logs must hold it)
is one line naming it, exit 2, whatever the terminal's encoding."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import polars as pl
import pytest
from specs import drop, mjcf_drop, toml

from impactlab.cli import main
from impactlab.files import DEEPEST_BYTES

NOT_TEXT = "the path is not UTF-8 text, which tables, reports and logs hold: rename it"
BAD = os.fsdecode(b"caf\xe9")  # a Latin-1 name, as an old archive holds
SHOWN = "caf\\xe9"  # as a message shows it


@pytest.fixture(scope="module")
def logs(record_spec) -> list[Path]:
    spec = drop("names", z=0.3, max_time=0.4, sweep={"ball.mass": [1.0, 2.0]})
    return record_spec("names", toml(spec))


def impactlab(*args: str | Path, cwd: Path) -> tuple[int, str, str]:
    """`python -m impactlab ARGS` with a strict UTF-8 terminal (a user's en_US.UTF-8 locale,
    where printing a name that is not UTF-8 would raise): exit code, stdout, stderr."""
    env = {**os.environ, "PYTHONIOENCODING": "utf-8:strict"}
    done = subprocess.run(
        [sys.executable, "-m", "impactlab", *map(str, args)],
        capture_output=True,
        cwd=cwd,
        env=env,
        timeout=300,
    )
    return done.returncode, done.stdout.decode(), done.stderr.decode()


def errors(err: str) -> list[str]:
    assert "Traceback" not in err, err
    return [line for line in err.splitlines() if line.startswith("impactlab: error: ")]


@pytest.mark.slow
@pytest.mark.parametrize("command", ["analyze", "replay"])
def test_a_log_named_like_a_pattern_is_that_log(tmp_path, logs, capsys, monkeypatch, command):
    """`run[1].mcap` beside `run1.mcap` (which the pattern matches) is `run[1].mcap`."""
    shutil.copy(logs[0], tmp_path / "run[1].mcap")
    shutil.copy(logs[1], tmp_path / "run1.mcap")
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    options = ["--no-figures"] if command == "analyze" else []
    assert main([command, "run[1].mcap", "-o", str(out), *options]) == 0
    if command == "analyze":
        assert pl.read_parquet(out / "runs.parquet")["file"].to_list() == ["run[1].mcap"]
    else:
        assert sorted(p.name for p in out.iterdir()) == ["run[1].rrd"]
    capsys.readouterr()


@pytest.mark.slow
def test_names_that_are_not_text(tmp_path, logs):
    """A log, a folder of logs, an output folder, a spec, a spec's folder, an MJCF model's
    folder whose names are not UTF-8: one line each, naming it as its bytes; the other inputs
    still done; replay, whose recordings hold no name, writes them."""
    folder = tmp_path / BAD
    folder.mkdir()
    shutil.copy(logs[0], folder / "a.mcap")
    shutil.copy(logs[1], tmp_path / f"{BAD}.mcap")
    (folder / "drop.toml").write_text(toml(drop("t", max_time=0.01)))
    (tmp_path / f"{BAD}.toml").write_text(toml(drop("t", max_time=0.01)))
    (folder / "model.xml").write_text(mjcf_drop("m", "sphere", "0.1", 0.3))
    cases = [  # argv, exit code, the input named in the one error line
        (["analyze", f"{BAD}.mcap", "-o", "out"], 2, f"{SHOWN}.mcap: 1 log(s): {NOT_TEXT}"),
        (["analyze", BAD, "-o", "out"], 2, f"{SHOWN}: 1 log(s): {NOT_TEXT}"),
        (["analyze", BAD, str(logs[0]), "-o", "out"], 1, f"{SHOWN}: 1 log(s): {NOT_TEXT}"),
        (["analyze", str(logs[0]), "-o", f"{BAD}/out"], 2, f"{SHOWN}/out: {NOT_TEXT}"),
        (["record", f"{BAD}.toml", "-o", "logs"], 2, f"{SHOWN}.toml: {NOT_TEXT}"),
        (["record", f"{BAD}/drop.toml", "-o", "logs"], 2, f"{SHOWN}/drop.toml: {NOT_TEXT}"),
        (
            ["record", f"{BAD}/model.xml", "--duration", "0.01", "-o", "logs"],
            2,
            f"{SHOWN}/model.xml: {NOT_TEXT}",
        ),
    ]
    for argv, code, line in cases:
        got, _, err = impactlab(*argv, cwd=tmp_path)
        assert (got, errors(err)) == (code, [f"impactlab: error: {line}"]), argv
    assert (tmp_path / "out" / "runs.parquet").is_file()  # the one log among others
    assert not (tmp_path / "logs").exists() and not (folder / "out").exists()
    got, out, err = impactlab("replay", BAD, f"{BAD}.mcap", "-o", f"{BAD}/rrd", cwd=tmp_path)
    assert got == 0 and not errors(err)
    assert sorted(os.listdir(folder / "rrd")) == ["a.rrd", f"{BAD}.rrd"]
    assert f"wrote {SHOWN}/rrd/{SHOWN}.rrd" in out


@pytest.mark.parametrize("command", ["record", "analyze", "replay"])
def test_an_output_folder_too_deep_for_its_files_is_named(tmp_path, logs, capsys, command):
    """An output folder whose path leaves no room under PATH_MAX for the files written in it:
    one line naming the folder (before: the log, or a traceback), exit 2, nothing made."""
    room = os.pathconf("/", "PC_PATH_MAX") - 1 - DEEPEST_BYTES
    deep = tmp_path.joinpath(*["d" * 200] * (room // 201 + 1))
    spec = tmp_path / "t.toml"
    spec.write_text(toml(drop("t", max_time=0.01)))
    given = str(spec) if command == "record" else str(logs[0])
    assert main([command, given, "-o", str(deep)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"impactlab: error: {deep}: the path is too long")
    assert not (tmp_path / ("d" * 200)).exists()


@pytest.mark.slow
@pytest.mark.parametrize("length", [254, 255])
def test_an_output_file_of_the_longest_name_is_written(tmp_path, logs, capsys, length):
    """`replay -o NAME.rrd` with NAME.rrd of 254 and 255 bytes (its temporary name, cut to
    fit, is never longer than a name may be): written, nothing else left beside it."""
    out = tmp_path / ("é" * ((length - 4) // 2) + "x" * ((length - 4) % 2) + ".rrd")
    assert len(os.fsencode(out.name)) == length
    assert main(["replay", str(logs[0]), "-o", str(out)]) == 0
    assert [p.name for p in tmp_path.iterdir()] == [out.name] and out.stat().st_size > 0
    capsys.readouterr()


@pytest.mark.parametrize(
    "argv",
    [
        ["analyze", "{bad}", "-o", "out"],
        ["replay", "{bad}", "-o", "out"],
        ["info", "{bad}"],
        ["diff", "{bad}", "{bad}"],
        ["record", "{bad}", "-o", "out"],
        ["analyze", "--no-such-option\nx", "{bad}"],
    ],
)
def test_a_newline_in_a_name_stays_in_its_error_line(tmp_path, capsys, monkeypatch, argv):
    """Every error line is one line: a name holding a newline, a tab or an escape is shown
    with them escaped, never as lines of its own or a terminal sequence."""
    name = "bad\nimpactlab: error: forged\t\x1b[31m.mcap"
    (tmp_path / name).write_bytes(b"not a log")
    monkeypatch.chdir(tmp_path)
    try:
        code = main([a.replace("{bad}", name) for a in argv])
    except SystemExit as exit_:  # argparse's mistakes leave by SystemExit
        code = exit_.code
    err = capsys.readouterr().err
    assert code != 0
    (line,) = [line for line in err.splitlines() if ": error: " in line]
    assert "forged" not in line or "bad\\nimpactlab: error: forged\\t\\x1b[31m" in line
    assert "\x1b" not in err and "\t" not in err
