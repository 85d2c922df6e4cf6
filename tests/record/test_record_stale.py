"""Temporary files a killed job left are removed when the folder is recorded into again."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from specs import drop, toml, write
from waiting import wait_until

from impactlab.record import plan, record_runs
from impactlab.record.folder import log_path


def test_stale_temporary_files_of_the_runs_are_removed_and_others_kept(tmp_path):
    out = tmp_path / "logs"
    out.mkdir()
    runs = plan([write(tmp_path, drop(max_time=0.02))])
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    name = log_path(out, runs[0]).name
    stale = out / f"{name}.{dead}.partial"
    other = out / f"another-run.mcap.{dead}.partial"  # not a run of this job: left alone
    stale.write_bytes(b"half")
    other.write_bytes(b"half")
    [result] = record_runs(runs, out, threads=1)
    assert result.status == "recorded"
    assert not stale.exists() and other.exists()


def test_temporary_files_of_a_dead_unreaped_process_are_stale(tmp_path):
    """A process that has exited but is not reaped yet (a zombie: its parent was killed too,
    or does not wait) writes nothing more: its temporary files are removed; those of this
    process (another thread's) are kept."""
    out = tmp_path / "logs"
    out.mkdir()
    runs = plan([write(tmp_path, drop(max_time=0.02))])
    name = log_path(out, runs[0]).name
    zombie = os.fork()
    if zombie == 0:
        os._exit(0)
    try:
        wait_until(lambda: _state(zombie) == "Z", what="a zombie")
        stale = out / f"{name}.{zombie}.{zombie}.partial"
        mine = out / f"{name}.12345.{os.getpid()}.partial"  # another thread of this process
        stale.write_bytes(b"half")
        mine.write_bytes(b"half")
        [result] = record_runs(runs, out, threads=1)
        assert result.status == "recorded"
        assert not stale.exists() and mine.exists()
    finally:
        os.waitpid(zombie, 0)


def _state(pid: int) -> str:
    return Path(f"/proc/{pid}/stat").read_bytes().rpartition(b")")[2].split()[0].decode()


KILLED = """
import ctypes, json, os, signal, subprocess, sys, time
from pathlib import Path
spec, out, found = sys.argv[1:]
ctypes.CDLL(None).prctl(36, 1)  # PR_SET_CHILD_SUBREAPER: orphans are reparented here, unreaped
job = subprocess.Popen([sys.executable, "-m", "impactlab", "record", spec, "-o", out],
                       start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
deadline = time.monotonic() + 300
while not list(Path(out).glob("*.partial")) and time.monotonic() < deadline:
    time.sleep(0.01)
workers = {int(p.name.split(".")[-2]) for p in Path(out).glob("*.partial")} - {job.pid}
os.killpg(job.pid, signal.SIGKILL)  # the whole process group, the job and its workers
job.wait()
while any(os.path.exists(f"/proc/{w}") and open(f"/proc/{w}/stat").read().rsplit(")", 1)[1].split()[0] != "Z" for w in workers):
    time.sleep(0.01)
states = {w: open(f"/proc/{w}/stat").read().rsplit(")", 1)[1].split()[0] for w in workers}
again = subprocess.run([sys.executable, "-m", "impactlab", "record", spec, "-o", out],
                       capture_output=True, text=True)
json.dump({"workers": sorted(workers), "states": states, "again": [again.returncode, again.stderr],
           "left": sorted(p.name for p in Path(out).iterdir())}, open(found, "w"))
for _ in workers:
    os.wait()
"""


@pytest.mark.slow
def test_a_rerun_after_the_whole_job_was_killed_removes_its_workers_files(tmp_path):
    """SIGKILL of the job's process group: its forked workers die unreaped (their new parent,
    here, does not wait); a re-run right away counts them dead, removes their temporary files
    and records what they were writing."""
    spec = tmp_path / "slow.toml"
    sweep = {"ball.mass": [1.0 + 0.1 * i for i in range(6)]}
    spec.write_text(toml(drop("slow", timestep=0.0001, max_time=2.0, every=10, sweep=sweep)))
    out, found = tmp_path / "logs", tmp_path / "found.json"
    done = subprocess.run(
        [sys.executable, "-c", KILLED, str(spec), str(out), str(found)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(found.read_text())
    assert result["workers"] and set(result["states"].values()) == {"Z"}, result
    assert result["again"][0] == 0, result["again"][1]
    assert len(result["left"]) == 6 and all(n.endswith(".mcap") for n in result["left"]), result
