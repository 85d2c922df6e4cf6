"""Real processes: starting `impactlab record`, waiting for a state (a log file open, workers
started, a server up), stopping it with a signal.

A test waits for what it needs, never for a time; the only clock here is a guard that keeps a
hung process from hanging the suite. It is no speed requirement: it is set far above every
wait measured on a loaded machine (load average 10 on 2 cores).
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from paths import ROOT

HANG_GUARD_S = 300.0


def wait_until(
    done: Callable[[], bool],
    proc: subprocess.Popen | None = None,
    *,
    what: str,
    output: Callable[[], object] | None = None,
    poll_s: float = 0.02,
) -> None:
    """Poll `done()` until it is true; fail at once if `proc` ends first, with its output
    (`output()` where it writes to a file)."""
    guard = time.monotonic() + HANG_GUARD_S
    while not done():
        if proc is not None and proc.poll() is not None:
            said = output() if output is not None else proc.communicate()
            pytest.fail(f"the process ended before {what}: {said}")
        if time.monotonic() > guard:
            pytest.fail(f"no sign of {what} after {HANG_GUARD_S:.0f} s: the process hangs")
        time.sleep(poll_s)


def record_process(spec: Path, out: Path, *args: str) -> subprocess.Popen:
    """`impactlab record SPEC -o OUT ARGS` as a process of its own, its output piped."""
    return subprocess.Popen(
        [sys.executable, "-m", "impactlab", "record", str(spec), "-o", str(out), *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def interrupt(
    proc: subprocess.Popen, sig: int = signal.SIGTERM, *, within_s: float = 60.0
) -> tuple[str, str]:
    """Send `sig` and return the process' (stdout, stderr) once it has ended, which must be
    within `within_s`, a hang guard far above the time it takes (a job stops between two
    chunks, in well under a second; a run left to its end takes minutes)."""
    proc.send_signal(sig)
    try:
        return proc.communicate(timeout=within_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise AssertionError(f"signal {sig} did not stop the job within {within_s} s") from None
