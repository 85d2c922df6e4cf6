"""Recording over forked worker processes (the processes executor with `start="fork"`): the
same logs, progress as runs finish, and every fault a worker can meet (killed, a bug,
interrupted) ends in complete logs or none."""

from __future__ import annotations

import dataclasses
import os
import sys
import threading
from pathlib import Path

import pytest
from specs import drop, toml
from waiting import interrupt, record_process, wait_until

from impactlab.executors.processes import ProcessExecutor, can_fork
from impactlab.progress import ProgressEvent
from impactlab.record import batch, plan, record_runs
from impactlab.record.recorder import task_ranges

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forks on Linux")


def _spec(tmp_path: Path, runs: int, max_time: float = 0.3) -> Path:
    path = tmp_path / f"forked_{runs}_{max_time:g}.toml"
    masses = [1.0 + 0.5 * i for i in range(runs)]
    path.write_text(toml(drop("forked", z=0.5, max_time=max_time, sweep={"ball.mass": masses})))
    return path


def test_tasks_are_consecutive_and_never_empty():
    for runs in (1, 5, 7, 37, 1000):
        for slots in (1, 2, 3, 7, 20):
            ranges = task_ranges(runs, slots)
            assert [i for r in ranges for i in r] == list(range(runs))  # consecutive, all
            assert all(ranges) and len({len(r) for r in ranges[:-1]}) <= 1  # one size


def test_forked_logs_equal_one_process_logs(tmp_path, monkeypatch):
    """Two worker processes write byte for byte the logs one process writes (same machine,
    same session), and report every run once, as it finishes."""
    runs = plan([_spec(tmp_path, 5)])
    assert can_fork()
    events: list[ProgressEvent] = []
    calls = []
    real = ProcessExecutor.map

    def spy(self, *args, **kwargs):
        calls.append((self.start, self.workers))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(ProcessExecutor, "map", spy)
    two = record_runs(runs, tmp_path / "two", threads=2, progress=events.append)
    one = record_runs(runs, tmp_path / "one", threads=1)
    assert calls == [("fork", 2)]
    assert [r.run_id for r in two] == [r.info.run_id for r in runs]
    for a, b in zip(two, one, strict=True):
        assert (a.status, a.outcome, a.steps, a.logged) == (b.status, b.outcome, b.steps, b.logged)
        assert a.path.read_bytes() == b.path.read_bytes()
    assert [e.done for e in events if e.line is None] == list(range(len(runs) + 1))


def test_a_killed_worker_fails_only_its_unreported_runs(tmp_path):
    """A worker that dies while building its second run: its runs not yet logged fail with
    the reason, the other worker's runs are complete, the temporary file of the log it was
    writing is removed."""
    runs = list(plan([_spec(tmp_path, 4)]))

    def die():
        os._exit(9)

    runs[3] = dataclasses.replace(runs[3], build=die)
    result = record_runs(runs, tmp_path / "logs", threads=2)
    by_id = {r.run_id: r for r in result}
    status = [by_id[r.info.run_id].status for r in runs]
    assert status[:2] == ["recorded"] * 2  # the other worker's share
    assert by_id[runs[3].info.run_id].reason == "worker process died (exit code 9)"
    assert status[3] == "failed"
    assert status[2] in ("recorded", "failed")  # logged before the worker died, or not
    assert sorted(p.name for p in (tmp_path / "logs").iterdir()) == sorted(
        r.path.name for r in result if r.status == "recorded"
    )


def test_a_bug_in_a_worker_fails_its_runs_with_the_reason(tmp_path):
    """An exception in a worker (a bug) fails the runs of its task, with the exception's
    type and message, as on any executor; nothing is left in the folder."""
    runs = list(plan([_spec(tmp_path, 2)]))

    def broken(*args, **kwargs):
        raise ZeroDivisionError("a bug")
        yield

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(batch, "requests", broken)
        result = record_runs(runs, tmp_path / "logs", threads=2)
    assert [(r.status, r.reason) for r in result] == [("failed", "ZeroDivisionError: a bug")] * 2
    assert not list((tmp_path / "logs").iterdir())


def test_with_another_thread_running_it_records_in_one_process(tmp_path, monkeypatch):
    """Forking a process with other threads is unsafe: then the job stays in this process."""
    runs = plan([_spec(tmp_path, 3)])

    def refuse(*args, **kwargs):
        raise AssertionError("forked with another thread running")

    monkeypatch.setattr(ProcessExecutor, "map", refuse)
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        assert not can_fork()
        result = record_runs(runs, tmp_path / "logs", threads=2)
    finally:
        stop.set()
        other.join()
    assert [r.status for r in result] == ["recorded"] * 3


@pytest.mark.slow
def test_sigterm_stops_the_workers_and_leaves_nothing(tmp_path):
    """SIGTERM to `impactlab record` while two workers write long runs: exit 130 within
    seconds, no log, no temporary file, no worker left running."""
    spec = _spec(tmp_path, 2, max_time=1000.0)
    text = spec.read_text().replace("timestep = 0.001", "timestep = 0.0001")
    spec.write_text(text + "[logging]\nevery = 100\n")
    out = tmp_path / "logs"
    proc = record_process(spec, out, "--allow-large")
    wait_until(lambda: len(list(out.glob("*.partial"))) >= 2, proc, what="two workers writing")
    workers = [int(p.name.split(".")[-2]) for p in out.glob("*.partial")]
    assert proc.pid not in workers
    _, stderr = interrupt(proc)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr and "impactlab: interrupted" in stderr
    assert list(out.iterdir()) == []
    for pid in workers:
        assert not Path(f"/proc/{pid}").exists() or "Z" in _state(pid), pid


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2]
    except FileNotFoundError:
        return "gone"


@pytest.mark.parametrize("threads", [1, 2])  # here, and over forked workers
def test_a_run_that_cannot_be_written_fails_alone(tmp_path, threads):
    """A folder where one log should go fails that run only (not a full disk: the others
    are written); recorded again once the folder is gone."""
    runs = plan([_spec(tmp_path, 3)])
    out = tmp_path / "logs"
    blocked = out / f"{runs[1].info.run_id}.mcap"
    blocked.mkdir(parents=True)
    result = record_runs(runs, out, threads=threads)
    assert [r.status for r in result] == ["recorded", "failed", "recorded"]
    assert result[1].reason.startswith("cannot write the log: IsADirectoryError")
    blocked.rmdir()
    again = record_runs(runs, out, threads=threads)
    assert [r.status for r in again] == ["reused", "recorded", "reused"]
