"""Work that cannot finish is refused before it starts (one line, exit 2) unless allowed
explicitly; wrong option values are one line too."""

from __future__ import annotations

import subprocess
import sys
from collections import namedtuple

import pytest
import specs
from paths import ROOT
from specs import ball, drop, toml

import impactlab
from impactlab.cli import main
from impactlab.files import OutputError
from impactlab.record import work

GOOD = toml(drop(max_time=0.05))


def one_line(capsys, code: int) -> str:
    captured = capsys.readouterr()
    assert code == 2, captured
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    return lines[0]


@pytest.mark.parametrize(
    ("overrides", "words"),
    [
        (["options.timestep=1e-7", "stop.max_time=1000"], "a run of 1e+10 steps > 1e+08"),
        (["options.timestep=1e-6", "stop.max_time=500"], "a run of 5e+08 steps > 1e+08"),
    ],
)
def test_a_run_too_long_is_refused(tmp_path, capsys, overrides, words):
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD)
    out = tmp_path / "out"
    args = ["record", str(spec), "-o", str(out)] + [x for o in overrides for x in ("--set", o)]
    line = one_line(capsys, main(args))
    assert line.startswith(f"impactlab: error: {spec}: too much work: ")
    assert words in line and "--allow-large" in line
    assert not out.exists()


@pytest.mark.slow
def test_a_million_run_sweep_is_refused_without_expanding_it(tmp_path):
    """A 1000 x 1000 sweep: refused at once (it used to plan for minutes, memory growing)."""
    values = ", ".join(f"{1 + i}" for i in range(1000))
    spec = tmp_path / "spec.toml"
    spec.write_text(
        GOOD
        + f'[sweep]\n"ball.mass" = [{values}]\n"ball.vel" = ['
        + ", ".join(f"[0, 0, {i}]" for i in range(1000))
        + "]\n"
    )
    proc = subprocess.run(
        [sys.executable, "-m", "impactlab", "record", str(spec), "-o", str(tmp_path / "out")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip().splitlines() == [
        f"impactlab: error: {spec}: too much work: 1,000,000 runs > 100,000 (1,000,000 run(s)); "
        "check the timestep, time limit and sweep, or pass --allow-large to record it anyway"
    ]


def test_allow_large_goes_ahead(tmp_path, capsys, monkeypatch):
    """With the limits made small, a 3-run sweep is refused, and recorded with --allow-large."""
    monkeypatch.setattr(work, "MAX_RUNS", 2)
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD + '[sweep]\n"ball.mass" = [1.0, 2.0, 3.0]\n')
    out = tmp_path / "out"
    assert "3 runs > 2" in one_line(capsys, main(["record", str(spec), "-o", str(out)]))
    assert main(["record", str(spec), "-o", str(out), "--allow-large"]) == 0
    assert len(list(out.glob("*.mcap"))) == 3
    capsys.readouterr()
    with pytest.raises(work.WorkError):
        impactlab.plan(spec)
    assert len(impactlab.plan(spec, allow_large=True)) == 3


def test_logs_larger_than_the_free_space_are_refused(tmp_path, capsys, monkeypatch):
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(work.shutil, "disk_usage", lambda _: usage(10_000, 9_000, 1_000))
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD)
    out = tmp_path / "out"
    line = one_line(capsys, main(["record", str(spec), "-o", str(out)]))
    assert line.startswith(f"impactlab: error: {out}: not enough space: about ")
    assert "1 kB free" in line and not list(out.glob("*.mcap"))
    assert main(["record", str(spec), "-o", str(out), "--allow-large"]) == 0
    capsys.readouterr()


@pytest.mark.parametrize("bodies", [1, 2])
@pytest.mark.parametrize("max_time", [0.002, 0.05, 5.0])
def test_the_estimate_is_an_upper_bound_of_the_log(tmp_path, capsys, max_time, bodies):
    """The estimated log size is within a factor of two above the real one, from logs of three
    rows, where what every log carries is nearly all, to logs of 5,000 rows."""
    free = {"a": ball(1.0), "b": ball(1.0, x=1.0)} if bodies == 2 else {"ball": ball(1.0)}
    spec = tmp_path / "spec.toml"
    spec.write_text(toml(specs.spec("e", free, max_time=max_time)))
    (run,) = impactlab.plan(spec)
    result = impactlab.record([run], out=tmp_path / "out")
    assert result[0].steps == run.work.steps  # the run went to its time limit
    size = result[0].path.stat().st_size
    assert size <= run.work.log_bytes <= 2 * size, (size, run.work)


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["-o", ""], "impactlab record: error: argument -o/--out: must not be empty"),
        (["--duration", "inf"], "argument --duration: must be a finite number of seconds > 0"),
        (["--duration", "nan"], "argument --duration: must be a finite number of seconds > 0"),
        (["--duration", "abc"], "argument --duration: must be a number of seconds, got 'abc'"),
        (["--executor", "foo"], "argument --executor: invalid choice: 'foo'"),
        (["--nope"], "unrecognized arguments: --nope"),
    ],
)
def test_wrong_option_values_are_one_line(tmp_path, capsys, monkeypatch, args, words):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "spec.toml").write_text(GOOD)
    with pytest.raises(SystemExit) as exc:
        main(["record", "spec.toml", *args])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and words in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["spec.toml"]


def test_an_empty_output_folder_in_the_api(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "spec.toml").write_text(GOOD)
    with pytest.raises(OutputError, match="must not be empty"):
        impactlab.record("spec.toml", out="")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["spec.toml"]


def test_mjcf_duration_too_long(tmp_path, capsys):
    model = tmp_path / "m.xml"
    model.write_text(
        '<mujoco><worldbody><body><freejoint/><geom size="0.1"/></body></worldbody></mujoco>'
    )
    line = one_line(
        capsys, main(["record", str(model), "--duration", "1e12", "-o", str(tmp_path / "o")])
    )
    assert "m.xml: --duration: an MJCF model needs --duration SECONDS, > 0 and <= 1e+09" in line
    line = one_line(
        capsys, main(["record", str(model), "--duration", "1e6", "-o", str(tmp_path / "o")])
    )
    assert "too much work: a run of 5e+08 steps" in line
