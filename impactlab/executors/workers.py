"""The worker processes of the processes executor: each is fed one task at a time on its own
pipe, so the parent always knows which task a worker holds.

A worker is spawned (a fresh interpreter), or forked with the function and the items of one
`map` in its memory (then a task is only its index, nothing is pickled), and talks to its
parent over one `multiprocessing.Pipe`: it says `READY` once up, `STARTED` when it takes a
task, then sends the task's outcome; asked to (`PRELOAD`), it imports the modules its tasks
will need and says `PRELOADED`, so a parent that works too can give it tasks only once it
runs them at once. No queue, lock or semaphore is shared, so the workers need no POSIX
semaphores (no `/dev/shm`), and a worker that dies takes only its own task with it.

A worker never outlives its parent: on Linux the kernel sends it SIGTERM when the parent dies
(`prctl(PR_SET_PDEATHSIG)`, whatever killed the parent, SIGKILL included; set when the worker
starts, and the parent's pid is checked after it, in case the parent died first); everywhere,
an idle worker exits when its pipe closes. SIGTERM unwinds the worker's task like Ctrl-C (its
`finally` and `with` blocks run: temporary files are removed); Ctrl-C itself is left to the
parent, which stops the workers.
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib
import multiprocessing
import os
import signal
import sys
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from multiprocessing.reduction import ForkingPickler
from typing import Any

from impactlab.executors.base import describe_error

Inherited = tuple[Callable[[Any], Any], Sequence[Any]]
"""A forked worker's function and items (`map`'s), in its memory since the fork."""

READY = "ready"
STARTED = "started"
PRELOAD = "preload"  # (PRELOAD, module names): import them now, then say PRELOADED
PRELOADED = "preloaded"
PR_SET_PDEATHSIG = 1  # prctl(2): the signal a process gets when its parent dies
EXIT_TERMINATED = 128 + signal.SIGTERM  # a worker stopped by SIGTERM (its parent gone)
EXIT_MAIN_GUARD = 87  # a worker whose start ran the caller's script into the executor again
MAIN_GUARD_HINT = (
    "the processes executor starts each worker by importing your script again, and the "
    "script starts the work when imported: put the call under "
    '`if __name__ == "__main__":` (or use executor="local")'
)
TEST_SIGKILL_TASK = "IMPACTLAB_TEST_SIGKILL_TASK"
"""For tests only: the worker given the task of this index kills itself (SIGKILL)."""


def importing_main() -> bool:
    """Whether this process is a spawned child still importing its parent's main module (a
    script without the `__main__` guard reaching the executor again; multiprocessing's own
    check, `spawn._check_not_importing_main`, reads the same flag)."""
    return bool(getattr(multiprocessing.current_process(), "_inheriting", False))


def die_with_parent(parent: int) -> None:
    """Have the kernel send this process SIGTERM when its parent dies (Linux), and stop now
    if the parent is already gone."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    if os.getppid() != parent:  # it died before the request took effect
        raise SystemExit(EXIT_TERMINATED)


def _unwind(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def serve(conn: Connection, parent: int, inherited: Inherited | None = None) -> None:
    """A worker's life: take (index, pickled (fn, item), or None for `inherited`'s) from
    `conn`, say it started, run it, send the outcome back; until the pipe closes or None
    arrives."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C: the parent stops the workers
        signal.signal(signal.SIGTERM, _unwind)
        die_with_parent(parent)
        conn.send((READY, os.getpid()))
        while True:
            try:
                task = conn.recv()
            except EOFError:  # the parent closed the pipe (or died)
                break
            if task is None:
                break
            index, payload = task
            if isinstance(index, str):  # PRELOAD
                _preload(payload)
                conn.send((PRELOADED, os.getpid()))
                continue
            conn.send((STARTED, index))
            if os.environ.get(TEST_SIGKILL_TASK) == str(index):
                os.kill(os.getpid(), signal.SIGKILL)
            conn.send_bytes(_run(index, payload, inherited))
    except (KeyboardInterrupt, ConnectionError):  # SIGTERM, or the parent is gone
        raise SystemExit(EXIT_TERMINATED) from None
    _leave()


def _leave() -> None:
    """End a worker whose work is done without the interpreter's teardown of every module
    (0.1 s with polars loaded, 0.7 s with matplotlib, which `close` would wait for): each
    task closed its own files; the standard streams are flushed."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(0)


def _preload(modules: object) -> None:
    """Import the modules a task's function needs before the first task arrives (one that
    cannot be imported here fails the tasks that need it, with the reason, later)."""
    for name in modules if isinstance(modules, (list, tuple)) else ():
        with contextlib.suppress(Exception):
            importlib.import_module(str(name))


def _run(index: int, payload: bytes | None, inherited: Inherited | None) -> memoryview:
    """(index, value, error, exception) of the task, pickled: a function or item that cannot
    be unpickled here, or a value that cannot be pickled, is the task's failure; its exception
    goes along when it can be pickled (else None: the error says it)."""
    try:
        if payload is not None:
            fn, item = ForkingPickler.loads(payload)
        else:
            assert inherited is not None  # a task without its payload goes to forked workers
            fn, item = inherited[0], inherited[1][index]
        value = fn(item)
        return ForkingPickler.dumps((index, value, None, None))
    except Exception as exc:  # one failed item never stops the others
        failed = (index, None, describe_error(exc))
        try:
            data = ForkingPickler.dumps((*failed, exc))
            ForkingPickler.loads(data)  # the parent can read it back
            return data
        except Exception:  # an exception that does not pickle
            return ForkingPickler.dumps((*failed, None))


def death(exitcode: int | None) -> str:
    """Why a worker process ended, for its task's failure: "worker process died (signal
    SIGKILL)"."""
    if exitcode is not None and exitcode < 0:
        try:
            how = f"signal {signal.Signals(-exitcode).name}"
        except ValueError:
            how = f"signal {-exitcode}"
    else:
        how = f"exit code {exitcode}"
    return f"worker process died ({how})"
