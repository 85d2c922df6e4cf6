"""The processes executor: items spread over worker processes on this machine.

Workers are spawned by default (a fork would copy the thread pools of polars and MuJoCo in
whatever state they are): each imports the module of the function it will run (about half a
second), says it is up, and lives until `close`; a batch smaller than `min_items` therefore
runs here, one item after the other, as the local executor would, unless the workers are up
already. Functions and items must be picklable (module-level functions, plain data), as for
Ray. Asked to (`map(..., here=True)`, the analysis), this process runs tasks too, on a
thread, whenever it is free: it works from the start while one worker fewer start, so a
batch is never slower than in one process because of their start. With `start="fork"` (the
record job, from a process without other threads: `can_fork`), each `map` forks its workers
with the function and items in their memory (planned runs that build their model when read),
sends each task as its index and stops them when it ends.

A worker is fed one task at a time on its own `multiprocessing.Pipe`, only once it is up: no
queue, lock or semaphore is shared (no POSIX semaphores, no `/dev/shm`), and the parent always
knows which task a worker holds. So a worker that dies (killed, out of memory) fails only its
own task, with the reason ("worker process died (signal SIGKILL)"); it is replaced, and the
other tasks go on as if nothing happened. A worker never outlives its parent: on Linux the
kernel sends it SIGTERM when the parent dies (`prctl(PR_SET_PDEATHSIG)`, whatever killed the
parent; the parent's pid is checked after, in case it died first); everywhere, an idle worker
exits when its pipe closes. SIGTERM unwinds a worker's task like Ctrl-C (its `finally` blocks
run: temporary files are removed); Ctrl-C itself is left to the parent, which stops the
workers. When no worker process can be started at all, the tasks run here, in one process,
after a one-line warning. A script that reaches this executor again while a worker imports it
(no `if __name__ == "__main__":` guard) is an `ExecutorError` saying so.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import importlib
import logging
import multiprocessing
import os
import signal
import sys
import threading
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from multiprocessing.reduction import ForkingPickler
from typing import Any, Generic, TypeVar

from impactlab.executors.base import (
    PROCESS_MIN_ITEMS,
    ExecutorError,
    LocalExecutor,
    TaskOutcome,
    describe_error,
    run_task,
)

R = TypeVar("R")
Inherited = tuple[Callable[[Any], Any], Sequence[Any]]  # a forked worker's function and items

READY = "ready"  # what a worker says once up, the modules it was given imported
MAX_FAILED_STARTS = 3  # workers in a row that die before they are up: run the rest here
STOP_SECONDS = 5.0  # how long `close` waits for a worker to stop before it kills it
PR_SET_PDEATHSIG = 1  # prctl(2): the signal a process gets when its parent dies
EXIT_TERMINATED = 128 + signal.SIGTERM  # a worker stopped by SIGTERM (its parent gone)
EXIT_MAIN_GUARD = 87  # a worker whose start ran the caller's script into the executor again
MAIN_GUARD_HINT = (
    "the processes executor starts each worker by importing your script again, and the "
    "script starts the work when imported: put the call under "
    '`if __name__ == "__main__":` (or use executor="local")'
)
NO_WORKERS = (
    "impactlab: warning: cannot start worker processes (%s); running the tasks here, in one process"
)
TEST_SIGKILL_TASK = "IMPACTLAB_TEST_SIGKILL_TASK"
"""For tests only: the worker given the task of this index kills itself (SIGKILL)."""

log = logging.getLogger("impactlab")


def available_cpus() -> int:
    """The CPUs this process may run on (its affinity mask, else the machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def can_fork() -> bool:
    """Whether worker processes may be forked here: Linux, and no other Python thread."""
    return (
        sys.platform.startswith("linux")
        and "fork" in multiprocessing.get_all_start_methods()
        and threading.active_count() == 1
    )


def refuse_in_worker_start() -> None:
    """Stop a spawned worker still importing its parent's script (a script without the
    `__main__` guard) that reached the executor: the parent raises the guard's error.
    multiprocessing's own check, `spawn._check_not_importing_main`, reads the same flag."""
    if getattr(multiprocessing.current_process(), "_inheriting", False):
        raise SystemExit(EXIT_MAIN_GUARD)


@dataclass(eq=False)
class _Worker:
    """One worker process, its end of the pipe, and the task it holds."""

    process: BaseProcess
    conn: Connection
    ready: bool = False  # it said it is up (READY): it gets tasks from then on
    task: int | None = None  # the index of the item sent to it


class ProcessExecutor:
    """Items over `workers` processes (default: one per available CPU), spawned or forked
    (`start`, see the module docstring)."""

    name = "processes"

    def __init__(
        self,
        workers: int | None = None,
        min_items: int = PROCESS_MIN_ITEMS,
        *,
        start: str = "spawn",
    ) -> None:
        self.workers = max(1, workers or available_cpus())
        self.min_items = min_items
        self.start = start
        self._inherited: Inherited | None = None  # what forked workers hold (this `map`'s)
        self._pool: list[_Worker] = []
        self._failed_starts = 0  # MAX_FAILED_STARTS: no worker can start here, never again
        self._problem = ""  # why the last one could not

    @property
    def slots(self) -> int:
        return self.workers

    def map(
        self, fn: Callable[[Any], R], items: Sequence[Any], *, here: bool = False
    ) -> Iterator[TaskOutcome[R]]:
        """Yield one outcome per item as it finishes (here, in order, for a small batch).

        `here`: this process runs tasks too, the next one whenever it is free (while the
        workers start, and whenever they are all busy); one worker fewer is started (this
        process is one of the `slots`). Only for functions that cannot bring the process
        down: a task run here that crashes ends the caller. Not with forked workers (a
        thread of this process would be forked with them).
        """
        refuse_in_worker_start()
        small = len(items) < self.min_items and not self._pool
        if not items or self.workers < 2 or small or self._failed_starts >= MAX_FAILED_STARTS:
            yield from LocalExecutor().map(fn, items)
            return
        if self.start == "fork":
            self.close()  # workers forked for another map hold its items
            self._inherited, here = (fn, items), False
        pool = self._pool
        todo = deque(range(len(items)))
        size = min(self.workers - 1 if here else self.workers, len(items))
        mine = _Here(fn, items) if here else None
        try:
            # a worker still starting is waited for even when the others did every task: its
            # start may fail in a way the caller must hear (a script without the guard)
            while (
                todo or any(w.task is not None or not w.ready for w in pool) or (mine and mine.busy)
            ):
                self._grow(size, todo, _modules(fn))
                if not pool:  # no worker can start: say so once, run the rest here from now
                    if mine is not None and mine.busy:
                        yield mine.finish()
                    log.warning(NO_WORKERS, self._problem)
                    self._failed_starts = MAX_FAILED_STARTS
                    yield from (run_task(fn, items[i], i) for i in todo)
                    return
                yield from self._feed(todo, fn, items)
                if mine is not None and not mine.busy:
                    mine.start(todo)
                waiting = [w.conn for w in pool] + [w.process.sentinel for w in pool]
                if mine is not None and mine.busy:
                    waiting.append(mine.reader)
                elif not any(w.task is not None or not w.ready for w in pool):
                    continue  # every send failed: those workers are gone, start others
                ready = wait(waiting)
                news = [w for w in pool if w.conn in ready or w.process.sentinel in ready]
                done = [o for worker in news for o in self._hear(worker)]
                done.extend(self._feed(todo, fn, items))  # before the caller takes the outcomes
                if mine is not None and mine.reader in ready:
                    done.append(mine.finish())
                yield from done
        finally:
            for worker in [w for w in pool if w.task is not None]:  # stopped early: stop them
                _stop(worker.process)
                self._drop(worker)
            if mine is not None:
                mine.close()
            if self.start == "fork":
                self.close()
                self._inherited = None

    def prestart(self, modules: Sequence[str]) -> None:
        """Start the workers a `map(..., here=True)` will use now, each importing `modules`
        before it says it is up, so that they start while this process does something else
        (its own imports); they are stopped at once by `close` if no task came."""
        refuse_in_worker_start()
        if self.workers < 2 or self._pool or self.start == "fork":
            return
        self._grow(self.workers - 1, deque([0]), tuple(modules))

    def _grow(self, size: int, todo: deque[int], preload: tuple[str, ...]) -> None:
        """Start workers (importing `preload`) up to `size` while there are tasks for them."""
        while todo and len(self._pool) < size and self._failed_starts < MAX_FAILED_STARTS:
            try:
                self._pool.append(_start(self.start, self._inherited, preload))
            except OSError as exc:  # no process, pipe or memory to be had
                self._failed_start(describe_error(exc))

    def _failed_start(self, problem: str) -> None:
        self._failed_starts += 1
        self._problem = problem

    def _feed(
        self, todo: deque[int], fn: Callable[[Any], R], items: Sequence[Any]
    ) -> Iterator[TaskOutcome[R]]:
        """Give each idle worker that is up its next task (one that cannot be pickled fails
        here; one whose worker is gone waits for another)."""
        for worker in list(self._pool):
            while worker.ready and worker.task is None and todo:
                index = todo.popleft()
                try:  # a forked worker has them already
                    payload = None if self._inherited else ForkingPickler.dumps((fn, items[index]))
                except Exception as exc:  # the function or the item cannot be pickled
                    yield TaskOutcome(index, error=describe_error(exc), exception=exc)
                    continue
                try:
                    worker.conn.send((index, None if payload is None else bytes(payload)))
                except ConnectionError:
                    todo.appendleft(index)
                    yield from self._lost(worker)
                    break
                worker.task = index

    def _hear(self, worker: _Worker) -> Iterator[TaskOutcome[Any]]:
        """Take one message from a worker whose pipe or process has news."""
        try:
            message = worker.conn.recv() if worker.conn.poll() else None
        except (EOFError, ConnectionError):
            message = None
        except Exception as exc:  # its value cannot be unpickled here
            if worker.task is not None:
                yield TaskOutcome(worker.task, error=describe_error(exc), exception=exc)
                worker.task = None
            return
        if message is None:  # the pipe closed or the process ended: it died
            yield from self._lost(worker)
        elif message == READY:
            worker.ready = True
            self._failed_starts = 0
        else:
            worker.task = None
            yield message

    def _lost(self, worker: _Worker) -> Iterator[TaskOutcome[Any]]:
        """A worker died: its task fails with the reason; one that was not up yet is a
        failed start."""
        worker.process.join()
        code = worker.process.exitcode
        self._drop(worker)
        if not worker.ready:
            if code == EXIT_MAIN_GUARD:
                raise ExecutorError(MAIN_GUARD_HINT)
            self._failed_start(death(code))
        if worker.task is not None:
            yield TaskOutcome(worker.task, error=death(code))

    def _drop(self, worker: _Worker) -> None:
        if worker in self._pool:
            self._pool.remove(worker)
        worker.conn.close()
        worker.process.join()

    def close(self) -> None:
        """Stop the workers (a task still running is stopped with SIGTERM, a worker still
        starting is killed: no need to wait for it)."""
        pool, self._pool = self._pool, []
        for worker in pool:
            with contextlib.suppress(OSError):
                worker.conn.send(None)
            if worker.task is not None:
                worker.process.terminate()
            elif not worker.ready:
                worker.process.kill()
        for worker in pool:
            _stop(worker.process, terminate=False)
            worker.conn.close()

    def __enter__(self) -> ProcessExecutor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _Here(Generic[R]):
    """The task this process runs itself (`map(..., here=True)`), on a thread so that the
    loop goes on feeding the workers; `reader` is ready when it is done."""

    def __init__(self, fn: Callable[[Any], R], items: Sequence[Any]) -> None:
        self.fn, self.items = fn, items
        self.reader, self._writer = multiprocessing.Pipe(duplex=False)
        self.index: int | None = None
        self._outcome: TaskOutcome[R] | None = None

    @property
    def busy(self) -> bool:
        return self.index is not None

    def start(self, todo: deque[int]) -> None:
        """Take the next task of `todo` and start it (never the one the tests have a worker
        kill itself on, `TEST_SIGKILL_TASK`: that one waits for a worker)."""
        skip = os.environ.get(TEST_SIGKILL_TASK)
        self.index = next((i for i in todo if str(i) != skip), None)
        if self.index is not None:
            todo.remove(self.index)
            threading.Thread(target=self._run, args=(self.index,), daemon=True).start()

    def _run(self, index: int) -> None:
        try:
            self._outcome = run_task(self.fn, self.items[index], index)
        except BaseException as exc:  # SystemExit and the like: the task's failure
            self._outcome = TaskOutcome(index, error=describe_error(exc))
        finally:
            self._writer.send_bytes(b"")

    def finish(self) -> TaskOutcome[R]:
        """Wait for the task started here and take its outcome."""
        self.reader.recv_bytes()
        outcome, self._outcome, self.index = self._outcome, None, None
        assert outcome is not None  # `_run` always gives one
        return outcome

    def close(self) -> None:
        """Release the pipe (a task still running here finishes on its own; its outcome is
        dropped)."""
        if not self.busy:
            self.reader.close()
            self._writer.close()


def _start(method: str, inherited: Inherited | None, preload: tuple[str, ...]) -> _Worker:
    """Start one worker process (`method`: "spawn" or "fork", with `inherited` in its memory)
    that imports `preload`, and connect to it."""
    fork = method == "fork"
    context = multiprocessing.get_context("fork") if fork else multiprocessing.get_context("spawn")
    here, there = context.Pipe()
    sys.stdout.flush()  # a forked worker would write what is buffered here again
    sys.stderr.flush()
    process = context.Process(
        target=serve,
        args=(there, os.getpid(), inherited, preload),
        name="impactlab-worker",
        daemon=True,
    )
    try:
        process.start()
    except BaseException:
        here.close()
        raise
    finally:
        there.close()  # the worker's end: its copy is in the worker now
    return _Worker(process, here)


def _stop(process: BaseProcess, *, terminate: bool = True) -> None:
    """Wait for a worker to end (after SIGTERM when `terminate`); SIGKILL if it takes long."""
    if terminate:
        process.terminate()
    process.join(STOP_SECONDS)
    if process.is_alive():
        process.kill()
        process.join()


def _modules(fn: Callable[..., Any]) -> tuple[str, ...]:
    """The module a worker imports to run `fn` (a function or a `functools.partial` of one)."""
    module = getattr(getattr(fn, "func", fn), "__module__", None)
    return (module,) if isinstance(module, str) and module != "__main__" else ()


# ---------------------------------------------------------------------------------------------
# in the worker process


def serve(
    conn: Connection,
    parent: int,
    inherited: Inherited | None = None,
    preload: Sequence[str] = (),
) -> None:
    """A worker's life: import `preload`, say READY, then take (index, pickled (fn, item), or
    None for `inherited`'s) from `conn`, run it and send its outcome back; until the pipe
    closes or None arrives."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C: the parent stops the workers
        signal.signal(signal.SIGTERM, _unwind)
        die_with_parent(parent)
        for name in preload:  # one that cannot be imported fails its tasks, with the reason
            with contextlib.suppress(Exception):
                importlib.import_module(name)
        conn.send(READY)
        while True:
            try:
                task = conn.recv()
            except EOFError:  # the parent closed the pipe (or died)
                break
            if task is None:
                break
            index, payload = task
            if os.environ.get(TEST_SIGKILL_TASK) == str(index):
                os.kill(os.getpid(), signal.SIGKILL)
            outcome: TaskOutcome[Any]
            try:
                if payload is None:  # a forked worker's task: the items are in its memory
                    assert inherited is not None
                    fn, item = inherited[0], inherited[1][index]
                else:
                    fn, item = ForkingPickler.loads(payload)
            except Exception as exc:  # the function or item cannot be unpickled here
                outcome = TaskOutcome(index, error=describe_error(exc), exception=exc)
            else:
                outcome = run_task(fn, item, index)
            conn.send_bytes(_pickled(outcome))
    except (KeyboardInterrupt, ConnectionError):  # SIGTERM, or the parent is gone
        raise SystemExit(EXIT_TERMINATED) from None
    # leave without the interpreter's teardown of every module (0.1 s with polars loaded,
    # 0.7 s with matplotlib, which `close` would wait for): each task closed its own files
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(0)


def _pickled(outcome: TaskOutcome[Any]) -> bytes:
    """The outcome, pickled: a value that cannot be pickled is the task's failure; its
    exception goes along when the parent can read it back (else None: the error says it)."""
    try:
        data = bytes(ForkingPickler.dumps(outcome))
        if outcome.exception is not None:
            ForkingPickler.loads(data)  # the parent can read it back
        return data
    except Exception as exc:
        if outcome.exception is not None:
            return _pickled(dataclasses.replace(outcome, exception=None))
        return _pickled(TaskOutcome(outcome.index, error=describe_error(exc), exception=exc))


def _unwind(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def die_with_parent(parent: int) -> None:
    """Have the kernel send this process SIGTERM when its parent dies (Linux), and stop now
    if the parent is already gone."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    if os.getppid() != parent:  # it died before the request took effect
        raise SystemExit(EXIT_TERMINATED)


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
