"""Record jobs under faults: unstable physics, interrupted processes, unwritable or full disks,
and determinism whatever the batching. A finished run's log is never lost or left half-written.
"""

from __future__ import annotations

import errno
import multiprocessing
import os
import re
import signal
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from specs import SOFT, drop, toml
from waiting import interrupt, record_process, wait_until

from impactlab.cli import main
from impactlab.logs import writer as writer_module
from impactlab.logs.load import load_log
from impactlab.record import plan, record_runs
from impactlab.record import recorder as recorder_module
from impactlab.record import simulate as simulate_module


def spec_file(folder: Path, name: str, *, dt=0.0005, max_time=1.0, extra="") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.toml"
    spec = drop(name, z=0.5, timestep=dt, contact=SOFT, max_time=max_time)
    path.write_text(toml(spec) + extra + "\n")
    return path


def official_meta(path: Path) -> dict[str, dict[str, str]]:
    """The log's metadata records, read with the official reader (which needs the summary)."""
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        assert reader.get_summary() is not None
        return {m.name: dict(m.metadata) for m in reader.iter_metadata()}


def assert_complete(path: Path) -> None:
    meta = official_meta(path)
    assert "impactlab.outcome" in meta
    run = load_log(path)
    assert not run.partial, run.problems


# ---------------------------------------------------------------------------------------------
# unstable physics


@pytest.mark.slow
def test_unstable_run_in_a_sweep(tmp_path, capsys):
    """A contact time constant of one step with a tiny damping ratio. With RK4, the ball meets
    the plane inside a step's stages and leaves it with 1e8 J in one step, while no force acts
    at the step's ends: the integrator made energy no force explains, so that run stops as
    unstable at that step, is named on the console, and the job exits 1. With Euler the same
    contact pumps the same energy into the ball, but through the contact's own force: its work
    is booked to the contact, the residual does not grow, and that run completes (energy a
    force explains is never an instability, however large)."""
    sweep = (
        '[sweep]\n"contact.solref" = [[0.02, 1.0], [0.0005, 0.003]]\n'
        '"options.integrator" = ["Euler", "RK4"]'
    )
    spec = spec_file(tmp_path, "wobbly", extra=sweep)
    out = tmp_path / "logs"
    code = main(["record", str(spec), "-o", str(out)])
    stdout, _ = capsys.readouterr()
    assert code == 1
    assert "4 run(s) written" in stdout and "1 unstable" in stdout
    logs = sorted(out.glob("*.mcap"))
    assert len(logs) == 4
    outcomes = {p.name: official_meta(p)["impactlab.outcome"] for p in logs}
    (bad,) = [name for name, o in outcomes.items() if o["outcome"] == "unstable"]
    assert "solref=0.0005_0.003" in bad and "RK4" in bad
    assert "energy grew by" in outcomes[bad]["reason"]
    assert "in one step that no force explains" in outcomes[bad]["reason"]
    assert f"warning: {Path(bad).stem}: unstable: energy grew" in stdout
    for name, o in outcomes.items():
        if name != bad:
            assert o["outcome"] == "completed" and o["reason"] == "time limit 1 s"
    unstable = load_log(out / bad)
    assert not unstable.partial and unstable.outcome == "unstable"
    # stopped at the step the energy appeared (the ball reaches the plane at 0.286 s)
    assert unstable.bodies["ball"]["t_s"].max() == pytest.approx(0.286, abs=1e-9)
    (pumped,) = [p for p in logs if "solref=0.0005_0.003" in p.name and "Euler" in p.name]
    run = load_log(pumped)
    gained = run.energy["total"][-1] - run.energy["total"][0]
    assert gained > 1e6 * run.energy["total"][0]  # the contact made energy ...
    assert run.work["contact_normal"][-1] == pytest.approx(gained, rel=0.01)  # ... and did work
    # the analysis keeps the run, with its outcome
    code = main(["analyze", str(out), "-o", str(tmp_path / "results")])
    capsys.readouterr()
    assert code == 0
    import polars as pl

    runs = pl.read_parquet(tmp_path / "results" / "runs.parquet")
    assert sorted(runs["outcome"].to_list()) == ["completed"] * 3 + ["unstable"]


def test_penetration_bound(tmp_path, capsys):
    """A penetration deeper than stop.max_penetration (fraction of the radius) is unstable."""
    spec = spec_file(tmp_path, "deep")
    out = tmp_path / "logs"
    code = main(["record", str(spec), "-o", str(out), "--set", "stop.max_penetration=0.001"])
    stdout, _ = capsys.readouterr()
    assert code == 1
    (log,) = out.glob("*.mcap")
    outcome = official_meta(log)["impactlab.outcome"]
    assert outcome["outcome"] == "unstable"
    assert outcome["reason"].startswith("penetration ") and "> 0.0001 m" in outcome["reason"]
    assert f"warning: {log.stem}: unstable: penetration" in stdout


def test_non_finite_state(tmp_path, capsys, monkeypatch):
    """A state that becomes NaN (injected into one run of a batch at step 100) stops
    that run as unstable with the rows before it; the batch's other runs are unaffected."""
    real = simulate_module._Run._steps

    def poisoned(run, n):
        real(run, n)
        if abs(run.model.body_mass[1] - 2.0) < 1e-9 and run.step0 == 0:
            run.rows[100:n] = np.nan  # what MuJoCo's sensors read once the state blew up

    monkeypatch.setattr(simulate_module._Run, "_steps", poisoned)
    spec = spec_file(tmp_path, "nan", extra='[sweep]\n"ball.mass" = [1.0, 2.0, 3.0]')
    out = tmp_path / "logs"
    code = main(["record", str(spec), "-o", str(out)])
    stdout, _ = capsys.readouterr()
    assert code == 1
    by_mass = {}
    for log in out.glob("*.mcap"):
        run = load_log(log)
        by_mass[run.sweep["bodies.ball.mass"]] = run
    assert by_mass[2.0].outcome == "unstable"
    assert by_mass[2.0].meta["reason"] == "state became non-finite at step 100"
    assert by_mass[2.0].bodies["ball"].height == 100  # steps 0..99, all finite
    assert np.isfinite(by_mass[2.0].bodies["ball"].drop("run_id").to_numpy()).all()
    assert "non-finite" in stdout
    assert by_mass[1.0].outcome == by_mass[3.0].outcome == "completed"
    assert by_mass[1.0].bodies["ball"].height == by_mass[3.0].bodies["ball"].height == 2001


# ---------------------------------------------------------------------------------------------
# interrupted jobs

SLOW_SWEEP = '[logging]\nevery = 10\n[sweep]\n"ball.mass" = [{}]'.format(
    ", ".join(f"{1 + 0.1 * i:.1f}" for i in range(9))
)


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL], ids=str)
def test_interrupted_job(tmp_path, capsys, sig):
    """Kill a recording process once its first log is complete: every *.mcap left is complete
    (.partial leftovers only after SIGKILL), and a re-run reuses them and runs the rest."""
    spec = spec_file(tmp_path, "slow", dt=0.0001, max_time=4.0, extra=SLOW_SWEEP)
    out = tmp_path / "logs"
    proc = record_process(spec, out)
    wait_until(lambda: any(out.glob("*.mcap")), proc, what="a log file")
    stdout, stderr = interrupt(proc, sig)
    assert "Traceback" not in stderr, stderr
    if sig == signal.SIGKILL:
        assert proc.returncode == -signal.SIGKILL
    else:
        assert proc.returncode == 130, (stdout, stderr)
        assert "impactlab: interrupted" in stderr
        assert not list(out.glob("*.partial"))
    done = sorted(out.glob("*.mcap"))
    assert 1 <= len(done) < 9
    for log in done:
        assert_complete(log)

    stale = list(out.glob("*.partial"))
    code = main(["record", str(spec), "-o", str(out)])
    rerun = capsys.readouterr().out
    assert code == 0
    assert f"reused {len(done)} complete log(s) in {out}/, running {9 - len(done)}" in rerun
    assert f"{9 - len(done)} run(s) written" in rerun
    assert len(list(out.glob("*.mcap"))) == 9
    assert not list(out.glob("*.partial")), stale  # stale leftovers of SIGKILL are removed
    for log in done:  # reused: not rewritten
        assert_complete(log)


@pytest.mark.slow
def test_overwrite_reruns_everything(tmp_path, capsys):
    spec = spec_file(tmp_path, "again", max_time=0.2, extra='[sweep]\n"ball.mass" = [1.0, 2.0]')
    out = tmp_path / "logs"
    assert main(["record", str(spec), "-o", str(out)]) == 0
    assert main(["record", str(spec), "-o", str(out)]) == 0
    assert "reused 2 complete log(s)" in capsys.readouterr().out
    # a log whose summary is cut off is not complete: it is recorded again
    victim = sorted(out.glob("*.mcap"))[0]
    victim.write_bytes(victim.read_bytes()[:-100])
    assert main(["record", str(spec), "-o", str(out)]) == 0
    assert "reused 1 complete log(s)" in capsys.readouterr().out
    assert_complete(victim)
    assert main(["record", str(spec), "-o", str(out), "--overwrite"]) == 0
    stdout = capsys.readouterr().out
    assert "reused" not in stdout and "2 run(s) written" in stdout


# ---------------------------------------------------------------------------------------------
# determinism


@pytest.mark.slow
def test_scheduling_does_not_change_the_logs(tmp_path):
    """Serial (this process) and forked (2 worker processes) recordings of the same spec file
    give byte-identical logs. Byte for byte holds because both are recorded on
    the same machine in the same process; across machines logs agree numerically only (see
    tests/e2e/test_golden.py)."""
    sweep = '[sweep]\n"ball.pos" = [[0.0, 0.0, 0.3], [0.1, 0.0, 0.4], [0.0, 0.2, 0.5], [0.0, 0.0, 0.6], [0.3, 0.0, 0.7]]'
    spec = spec_file(tmp_path, "same", max_time=0.8, extra=sweep)
    runs = plan([spec])
    serial = record_runs(runs, tmp_path / "serial", threads=1)
    forked = record_runs(runs, tmp_path / "forked", threads=2)
    assert [r.path.name for r in serial] == [r.path.name for r in forked]
    for a, b in zip(serial, forked, strict=True):
        assert a.path.read_bytes() == b.path.read_bytes(), a.path.name


# ---------------------------------------------------------------------------------------------
# disk


@pytest.mark.parametrize("where", ["parent is a file", "under /proc"])
def test_unwritable_target_fails_before_simulating(tmp_path, capsys, monkeypatch, where):
    spec = spec_file(tmp_path, "long", dt=0.0001, max_time=30.0)  # ~seconds of simulation
    blocker = tmp_path / "file.txt"
    blocker.write_text("not a folder")
    out = blocker / "logs" if where == "parent is a file" else Path("/proc/impactlab-test/logs")

    def forbidden(*args: object, **kwargs: object) -> None:
        raise AssertionError("simulated before checking the output folder")

    monkeypatch.setattr(recorder_module, "record_logs", forbidden)  # every way to simulate
    monkeypatch.setattr(simulate_module, "simulate", forbidden)
    code = main(["record", str(spec), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"impactlab: error: {out}: cannot write")
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt", "long.toml"]


class _FillingDisk:
    """A file whose writes fail with ENOSPC once the shared budget of bytes is spent (shared
    by every process of the job, as a disk is: `budget` is a multiprocessing.Value)."""

    def __init__(self, stream, budget) -> None:
        self._stream = stream
        self._budget = budget

    def write(self, data) -> int:
        size = len(memoryview(data).cast("B"))
        with self._budget.get_lock():
            if size > self._budget.value:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            self._budget.value -= size
        return self._stream.write(data)

    def __getattr__(self, name):
        return getattr(self._stream, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self._stream.close()


@pytest.mark.slow
def test_disk_full_while_writing(tmp_path, capsys, monkeypatch):
    """The disk fills while the logs are written (room for two and a half): one error line
    saying how many logs are complete, non-zero exit, every finished log intact, no
    half-written .mcap and no .partial left; with room again the job resumes."""
    spec = spec_file(
        tmp_path, "full", max_time=0.5, extra='[sweep]\n"ball.mass" = [1.0, 2.0, 3.0, 4.0]'
    )
    out = tmp_path / "logs"
    # one log's size, measured, sets a budget of two and a half logs
    probe = record_runs(plan([spec]), tmp_path / "probe")
    size = probe[0].path.stat().st_size
    budget = multiprocessing.get_context("fork").Value("q", int(2.5 * size))

    def filling_open(path, mode="r", *args, **kwargs):
        stream = open(path, mode, *args, **kwargs)  # noqa: SIM115
        return _FillingDisk(stream, budget) if "w" in mode else stream

    monkeypatch.setattr(writer_module, "open", filling_open, raising=False)
    code = main(["record", str(spec), "-o", str(out)])
    _, err = capsys.readouterr()
    assert code != 0
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("impactlab: error: ")
    assert "No space left on device" in lines[0]
    said = int(re.search(r"\((\d+) log\(s\) of this job written before it", lines[0]).group(1))
    logs = sorted(out.glob("*.mcap"))
    assert 1 <= len(logs) <= 2 and said <= len(logs), (said, logs)
    reference = {p.path.name: p.path for p in probe}
    for log in logs:
        assert log.read_bytes() == reference[log.name].read_bytes()  # same machine: intact
    assert not list(out.glob("*.partial"))
    # with space again, the job resumes where it stopped
    monkeypatch.undo()
    assert main(["record", str(spec), "-o", str(out)]) == 0
    assert f"reused {len(logs)} complete log(s)" in capsys.readouterr().out
    assert len(list(out.glob("*.mcap"))) == 4


@pytest.mark.parametrize("warnings", ["5", '"text"', '{"a": 1}', "null", "[1, "])
def test_a_reused_logs_odd_warnings_are_none(warnings):
    """A complete log's outcome record names its warnings as a JSON list; a damaged one (a
    number, a text, an object, broken JSON) reuses the log with no warning, never a TypeError."""
    from impactlab.record.results import RecordedRun

    run = RecordedRun.reused("r", Path("r.mcap"), {"outcome": "completed", "warnings": warnings})
    assert run.status == "reused" and run.warnings == ()
