"""Functions the executor tests run in worker processes: this module imports nothing heavy,
so a worker that imports it starts fast."""

from __future__ import annotations

import os
import signal
from pathlib import Path

MARKER = "IMPACTLAB_TEST_MARKER"


def die_on(item: str) -> tuple[str, int]:
    """In a worker: SIGKILL its own process on "die", else the item and the worker's pid."""
    if item == "die":
        os.kill(os.getpid(), signal.SIGKILL)
    return item, os.getpid()


def serve_after_a_failed_start(*args) -> None:
    """A worker's start that dies (SIGKILL) before the worker is up: the first time only when
    the environment names a marker file (made then), else every time."""
    marker = os.environ.get(MARKER)
    if marker is None or not os.path.exists(marker):
        if marker is not None:
            Path(marker).touch()
        os.kill(os.getpid(), signal.SIGKILL)
    from impactlab.executors.processes import serve

    serve(*args)
