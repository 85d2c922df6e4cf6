"""Two record jobs on the same sweep and folder at once: both succeed, and the folder holds
one complete log per run (each process writes under its own temporary name; a run the other
job finished first is reused, and when both finish a run, the same bytes replace each other)."""

from __future__ import annotations

import re
import subprocess
import sys
import threading

import pytest
from paths import ROOT
from specs import drop, toml

import impactlab
from impactlab.logs.load import load_log

SPEC = toml(drop("race", timestep=0.0001, max_time=1.5, sweep={"ball.mass": [1.0, 2.0, 3.0, 4.0]}))


@pytest.mark.slow
def test_two_jobs_on_one_sweep_and_folder(tmp_path):
    spec = tmp_path / "race.toml"
    spec.write_text(SPEC)
    out = tmp_path / "logs"
    cmd = [sys.executable, "-m", "impactlab", "record", str(spec), "-o", str(out)]
    jobs = [
        subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for _ in range(2)
    ]
    results = [(job.wait(timeout=120), *job.communicate()) for job in jobs]
    for code, stdout, stderr in results:
        assert code == 0 and stderr == "", (code, stdout, stderr)
        # each job wrote the runs it did not find complete (the other may have finished some,
        # or all of them, before this one started)
        written = re.search(r"(\d+) run\(s\) written", stdout)
        reused = re.search(r"reused (\d+) complete log\(s\)", stdout)
        assert written is not None, stdout
        assert int(written.group(1)) + (int(reused.group(1)) if reused else 0) <= 4, stdout
    logs = sorted(out.iterdir())
    assert len(logs) == 4 and all(p.suffix == ".mcap" for p in logs), logs  # no .partial left
    for log in logs:
        run = load_log(log)
        assert not run.partial and run.problems == [] and run.outcome == "completed", log
        assert run.energy.height == 15_001


@pytest.mark.parametrize("overwrite", [False, True])
def test_threads_of_one_process_record_into_one_folder(tmp_path, overwrite):
    """`impactlab.record` from four threads at once into one folder, each writing every run
    (with `overwrite`) or what it does not find complete: none fails, one complete log per
    run is left and no temporary file (each thread writes under its own temporary name)."""
    spec = tmp_path / "race.toml"
    spec.write_text(toml(drop("race", max_time=0.2, sweep={"ball.mass": [1.0, 2.0, 3.0]})))
    out = tmp_path / "logs"
    start = threading.Barrier(4)
    outcomes: list[object] = []

    def record() -> None:
        start.wait()
        try:
            outcomes.append(impactlab.record(spec, out=out, overwrite=overwrite))
        except Exception as exc:  # what the test is about: none
            outcomes.append(exc)

    threads = [threading.Thread(target=record) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not [o for o in outcomes if isinstance(o, Exception)], outcomes
    logs = sorted(out.iterdir())
    assert len(logs) == 3 and all(p.suffix == ".mcap" for p in logs), logs
    for log in logs:
        assert not load_log(log).partial
