"""Waiting for a real process to reach a state (a log file open, workers started, a server up).

A test waits for what it needs, never for a time; the only clock here is a guard that keeps a
hung process from hanging the suite. It is no speed requirement: it is set far above every
wait measured on a loaded machine (load average 10 on 2 cores).
"""

from __future__ import annotations

import subprocess
import time
from collections.abc import Callable

import pytest

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
