"""The processes executor under faults: a worker killed, the parent killed, a script without
the `__main__` guard, no usable /dev/shm, workers that cannot start. Each test fails on the
executor built on `concurrent.futures.ProcessPoolExecutor` (b15c755) and passes now."""

from __future__ import annotations

import _multiprocessing
import errno
import logging
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
import types
from pathlib import Path

import psutil
import pytest
from executor_tasks import MARKER, die_on, serve_after_a_failed_start
from paths import ROOT
from specs import drop, toml
from waiting import wait_until

from impactlab.analyze.batch import batches
from impactlab.executors import processes
from impactlab.executors.processes import TEST_SIGKILL_TASK, ProcessExecutor
from impactlab.logs.inputs import require_logs

pytestmark = pytest.mark.slow  # workers and parents killed (SIGKILL)

SIGKILLED = "worker process died (signal SIGKILL)"
SWEEP = toml(
    drop(
        "faults",
        z=0.3,
        timestep=0.0005,
        contact={"condim": 1, "solref": [0.02, 0.3]},
        max_time=0.6,
        sweep={"ball.mass": [round(1.0 + 0.1 * i, 1) for i in range(12)]},
    )
)


@pytest.fixture(scope="module")
def logs(record_spec, tmp_path_factory) -> Path:
    """A folder of 12 short logs of one bouncing ball (a sweep over its mass)."""
    folder = tmp_path_factory.mktemp("faults") / "logs"
    folder.mkdir()
    for path in record_spec("faults", SWEEP):
        shutil.copy(path, folder)
    return folder


def two_cpus() -> None:
    """Run the command line on two CPUs: two workers, and a batching the test can predict."""
    os.sched_setaffinity(0, sorted(os.sched_getaffinity(0))[:2])


def analyze(folder: Path, out: Path, *args: str, env: dict[str, str] | None = None, **kw):
    return subprocess.Popen(
        [sys.executable, "-m", "impactlab", "analyze", str(folder), "-o", str(out), *args],
        cwd=ROOT,
        text=True,
        env={**os.environ, **(env or {})},
        preexec_fn=two_cpus,
        **({"stdout": subprocess.PIPE, "stderr": subprocess.PIPE} | kw),
    )


def gone(process: psutil.Process) -> bool:
    """Whether the process has ended (a zombie waiting for its reaper has)."""
    try:
        return process.status() == psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return True


# ---------------------------------------------------------------------------------------------
# a worker dies


def test_a_dead_worker_fails_only_its_task_and_is_replaced():
    """The task whose worker was killed fails with the signal; every other task completes,
    also after both first workers died (their replacements take the rest)."""
    items = ["a", "die", "b", "c", "d", "e", "f", "g"]
    with ProcessExecutor(workers=2, min_items=1) as ex:
        outcomes = sorted(ex.map(die_on, items), key=lambda o: o.index)
        assert [o.error for o in outcomes] == [None, SIGKILLED, *[None] * 6]
        assert [o.value[0] for o in outcomes if o.ok] == ["a", "b", "c", "d", "e", "f", "g"]
        again = sorted(ex.map(die_on, ["die", "die", "x", "y", "z"]), key=lambda o: o.index)
    assert [o.error for o in again] == [SIGKILLED, SIGKILLED, None, None, None]
    first = {o.value[1] for o in outcomes if o.ok}
    later = {o.value[1] for o in again[2:]}
    assert os.getpid() not in later and not later & first  # done by the new workers


def test_a_worker_dead_before_it_is_up_loses_nothing(tmp_path, monkeypatch):
    """A worker that dies while it starts had not begun its task: the task is given to
    another worker, and every task completes."""
    monkeypatch.setattr(processes, "serve", serve_after_a_failed_start)
    monkeypatch.setenv(MARKER, str(tmp_path / "died-once"))
    with ProcessExecutor(workers=2, min_items=1) as ex:
        outcomes = sorted(ex.map(die_on, list("abcdef")), key=lambda o: o.index)
    assert (tmp_path / "died-once").exists()
    assert [o.value[0] for o in outcomes] == list("abcdef")
    assert all(o.ok and o.value[1] != os.getpid() for o in outcomes)


def test_the_command_line_fails_only_the_dead_workers_logs(logs, tmp_path):
    """`impactlab analyze` with figures: the worker given task 3 kills itself (SIGKILL). Only
    the logs of that task fail, one line each; the others are analyzed, the summary figures
    drawn by the workers after it (where a broken pool used to raise), the report written,
    exit code 1, no traceback."""
    out = tmp_path / "results"
    proc = analyze(logs, out, env={TEST_SIGKILL_TASK: "3"})
    stdout, stderr = proc.communicate(timeout=300)
    paths, _ = require_logs([logs])
    # two workers: 8 tasks per worker with figures (impactlab.analyze.batch.analyze_logs)
    lost = [paths[i] for i in batches([(p, p) for p in paths], parts=16)[3]]
    assert "Traceback" not in stderr, stderr
    assert proc.returncode == 1, (stdout, stderr)
    errors = [line for line in stderr.splitlines() if line.startswith("impactlab: error:")]
    assert errors == [f"impactlab: error: {p}: {SIGKILLED}" for p in lost]
    assert f"{len(paths) - len(lost)} run(s) analyzed, {len(lost)} failed" in stdout
    assert (out / "report.md").is_file()
    summary = {"bounce-decay-faults.png", "restitution-vs-speed.png", "study-faults.png"}
    assert summary <= {p.name for p in (out / "figures").glob("*.png")}


# ---------------------------------------------------------------------------------------------
# the parent dies


def test_workers_die_with_a_killed_parent(logs, tmp_path):
    """SIGKILL of `impactlab analyze` while its workers work: every process it started ends
    within seconds (PR_SET_PDEATHSIG), none is left orphaned."""
    # output to a file: orphaned workers would hold a pipe open (and `communicate` wait)
    with open(tmp_path / "output.txt", "w") as output:
        proc = analyze(logs, tmp_path / "results", stdout=output, stderr=output)
    parent = psutil.Process(proc.pid)
    workers: list[psutil.Process] = []

    def two_workers() -> bool:
        with_cmdline = []
        for child in parent.children(recursive=True):
            try:
                with_cmdline.append((child, " ".join(child.cmdline())))
            except psutil.NoSuchProcess:
                continue
        workers[:] = [child for child, line in with_cmdline if "--multiprocessing-fork" in line]
        return len(workers) >= 2

    output = (tmp_path / "output.txt").read_text
    wait_until(two_workers, proc, what="two worker processes", output=output)
    time.sleep(1.0)  # the workers import and take their first tasks
    started = parent.children(recursive=True)
    assert set(workers) <= set(started)
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 30  # a bound, not a speed requirement
    while not all(gone(p) for p in started) and time.monotonic() < deadline:
        time.sleep(0.05)
    left = [p for p in started if not gone(p)]
    for p in left:  # leave no orphan behind, even when the test fails
        p.kill()
    assert [p.pid for p in left] == []


ASK_DEATH_SIGNAL = """
import ctypes, os, sys
from impactlab.executors.processes import die_with_parent
die_with_parent(os.getppid() if sys.argv[1] == "right" else os.getppid() + 1)
got = ctypes.c_int()
ctypes.CDLL(None).prctl(2, ctypes.byref(got))  # PR_GET_PDEATHSIG
print(got.value)
"""


def test_a_worker_asks_for_its_parents_death_and_checks_its_pid():
    """The start of a worker: the kernel will send it SIGTERM when its parent dies, and a
    parent already gone (another pid than the one it was given) stops it at once."""
    run = [sys.executable, "-c", ASK_DEATH_SIGNAL]
    right = subprocess.run([*run, "right"], capture_output=True, text=True, check=True)
    assert int(right.stdout) == signal.SIGTERM
    wrong = subprocess.run([*run, "wrong"], capture_output=True, text=True)
    assert wrong.returncode == 128 + signal.SIGTERM and wrong.stdout == "", wrong.stderr


# ---------------------------------------------------------------------------------------------
# a script without the __main__ guard

NO_GUARD = """
import impactlab
result = impactlab.analyze({logs!r}, executor="processes")
print("analyzed", result.runs.height, "failed", len(result.failed))
"""


def test_a_script_without_the_main_guard_is_told_to_add_it(logs, tmp_path):
    script = tmp_path / "no_guard.py"
    script.write_text(textwrap.dedent(NO_GUARD.format(logs=str(logs))))
    proc = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=300, cwd=tmp_path
    )
    assert proc.returncode != 0, proc.stdout
    assert "analyzed" not in proc.stdout
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("impactlab.executors.base.ExecutorError: ")
    assert 'put the call under `if __name__ == "__main__":`' in last
    assert "RuntimeError" not in proc.stderr  # the workers stopped quietly
    assert proc.stderr.count("Traceback") == 1  # the script's own, ending in the message
    # with the guard, the same call works
    guarded = "if __name__ == '__main__':\n" + textwrap.indent(script.read_text(), "    ")
    script.write_text(guarded)
    proc = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=300, cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr
    assert "analyzed 12 failed 0" in proc.stdout


# ---------------------------------------------------------------------------------------------
# no /dev/shm, no worker


def no_semaphores(*args, **kwargs):
    raise OSError(errno.EROFS, os.strerror(errno.EROFS))


def test_workers_need_no_semaphores(monkeypatch, caplog):
    """POSIX semaphores live in /dev/shm: where it is read-only or missing, creating one
    fails with EROFS or ENOENT. The workers use none: they still run, with no warning."""
    import multiprocessing.synchronize  # noqa: F401  (its constants read SemLock once)

    monkeypatch.setattr(_multiprocessing, "SemLock", no_semaphores)
    with caplog.at_level(logging.WARNING), ProcessExecutor(workers=2, min_items=1) as ex:
        outcomes = sorted(ex.map(die_on, list("abcd")), key=lambda o: o.index)
    assert [o.value[0] for o in outcomes] == list("abcd")
    assert all(o.value[1] != os.getpid() for o in outcomes)
    assert caplog.messages == []


def read_only_shm() -> list[str] | None:
    """A command prefix running in a mount namespace of its own with a fresh read-only
    /dev/shm (a new tmpfs mounted there, invisible outside; never a remount of the real one),
    or None when this machine does not allow one."""
    if shutil.which("unshare") is None:
        return None
    inner = 'mount -t tmpfs -o ro tmpfs /dev/shm && exec "$@"'
    for flags in (["-m"], ["-r", "-m"]):
        prefix = ["unshare", *flags, "--propagation", "private", "sh", "-c", inner, "sh"]
        probe = [sys.executable, "-c", "open('/dev/shm/x', 'w')"]
        try:
            done = subprocess.run([*prefix, *probe], capture_output=True, text=True, timeout=60)
        except OSError:
            return None
        if "Read-only file system" in done.stderr:
            return prefix
    return None


def test_analysis_with_a_read_only_dev_shm(logs, tmp_path):
    """The real case, where this machine allows a mount namespace: `impactlab analyze` on a
    read-only /dev/shm analyzes every log in worker processes (no traceback, no warning)."""
    prefix = read_only_shm()
    if prefix is None:
        pytest.skip("no mount namespace here (unshare needs root or user namespaces)")
    command = [sys.executable, "-m", "impactlab", "analyze", str(logs), "-o", str(tmp_path)]
    done = subprocess.run(
        [*prefix, *command], capture_output=True, text=True, timeout=300, cwd=ROOT
    )
    assert done.returncode == 0, done.stderr
    assert not [x for x in done.stderr.splitlines() if not x.startswith("analyze: ")], done.stderr
    assert "12 run(s) analyzed, 0 failed" in done.stdout


def test_no_worker_can_start_runs_the_tasks_here_with_a_warning(monkeypatch, caplog):
    """Workers that die while they start, every time: after three the executor says so in
    one line and runs the tasks in this process."""
    monkeypatch.setattr(processes, "serve", serve_after_a_failed_start)
    monkeypatch.delenv(MARKER, raising=False)
    with caplog.at_level(logging.WARNING), ProcessExecutor(workers=2, min_items=1) as ex:
        outcomes = sorted(ex.map(die_on, list("abc")), key=lambda o: o.index)
    assert [o.value for o in outcomes] == [(x, os.getpid()) for x in "abc"]
    assert caplog.messages == [
        "impactlab: warning: cannot start worker processes (worker process died (signal "
        "SIGKILL)); running the tasks here, in one process"
    ]


def test_workers_that_cannot_be_created_run_the_tasks_here(monkeypatch, caplog):
    """No process to be had (fork fails with EAGAIN): one warning, the tasks run here."""

    def no_process(*args):
        raise OSError(errno.EAGAIN, os.strerror(errno.EAGAIN))

    monkeypatch.setattr(processes, "_start", no_process)
    with caplog.at_level(logging.WARNING), ProcessExecutor(workers=2, min_items=1) as ex:
        outcomes = sorted(ex.map(die_on, list("ab")), key=lambda o: o.index)
        assert [o.value for o in ex.map(die_on, ["c"])] == [("c", os.getpid())]
    assert [o.value for o in outcomes] == [("a", os.getpid()), ("b", os.getpid())]
    assert len(caplog.messages) == 1
    assert "cannot start worker processes (BlockingIOError: [Errno 11]" in caplog.messages[0]


# ---------------------------------------------------------------------------------------------
# tasks that cannot travel


def test_a_task_that_cannot_be_sent_or_loaded_fails_alone():
    """A function that cannot be pickled here, or not unpickled in the worker (its module
    exists only in this process), fails its own items with the reason; the others run."""
    only_here = types.ModuleType("impactlab_test_only_here")
    exec("def twice(x):\n    return 2 * x\n", only_here.__dict__)
    sys.modules[only_here.__name__] = only_here
    try:
        with ProcessExecutor(workers=2, min_items=1) as ex:
            sent = sorted(ex.map(only_here.twice, [1, 2, 3]), key=lambda o: o.index)
            assert all(o.error.startswith("ModuleNotFoundError: ") for o in sent), sent
            local = sorted(ex.map(lambda x: x, [1, 2]), key=lambda o: o.index)
            assert all("pickle" in o.error.lower() for o in local), local
            assert [o.value[0] for o in ex.map(die_on, ["ok"])] == ["ok"]
    finally:
        del sys.modules[only_here.__name__]
