"""The processes executor: items spread over worker processes on this machine.

Workers are spawned by default (a fork would copy the thread pools of polars and MuJoCo in
whatever state they are), so each pays the import of what its function needs once (about
half a second) and lives until `close`; a batch smaller than `min_items` therefore runs here,
one item after the other, as the local executor would, unless the workers are up already.
Functions and items must be picklable (module-level functions, plain data), as for Ray.
Asked to (`map(..., here=True)`, the analysis), this process runs tasks too, whenever it is
free: it works from the start while one worker fewer start, and a worker gets tasks once it
has imported the function's module, so a batch is never slower than in one process because
of their start. With `start="fork"` (the record job, from a process without other threads:
`can_fork`), each `map` forks its workers with the function and items in their memory
(planned runs that build their model when read), sends each task as its index and stops
them when it ends.

Each worker holds one task at a time (`impactlab.executors.workers`). So a worker that dies
(killed, out of memory) fails only the task it had started, with the reason ("worker process
died (signal SIGKILL)"); it is replaced, and the tasks not yet started go on as if nothing
happened. Workers die with this process, however it ends. When no worker process can be
started at all, the tasks run here, in one process, after a one-line warning. A script that
reaches this executor again while a worker imports it (no `if __name__ == "__main__":` guard)
is an `ExecutorError` saying so.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import multiprocessing
import os
import sys
import threading
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess
from multiprocessing.reduction import ForkingPickler
from typing import Any, TypeVar

from impactlab.executors.base import (
    PROCESS_MIN_ITEMS,
    ExecutorError,
    LocalExecutor,
    TaskOutcome,
    describe_error,
)
from impactlab.executors.here import HereTasks
from impactlab.executors.workers import (
    EXIT_MAIN_GUARD,
    MAIN_GUARD_HINT,
    PRELOAD,
    PRELOADED,
    READY,
    STARTED,
    Inherited,
    death,
    importing_main,
    serve,
)

R = TypeVar("R")

MAX_FAILED_STARTS = 3  # workers in a row that die before they are up: run the rest here
STOP_SECONDS = 5.0  # how long `close` waits for a worker to stop before it kills it

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
    """Stop a worker process whose start (importing the caller's script again) has reached
    the executor: the parent then raises the `__main__`-guard error (see the workers)."""
    if importing_main():
        raise SystemExit(EXIT_MAIN_GUARD)


@dataclass(eq=False)
class _Worker:
    """One worker process, its end of the pipe, and the task it holds."""

    process: BaseProcess
    conn: Connection
    ready: bool = False  # it said it is up
    task: int | None = None  # the index of the item sent to it
    started: bool = False  # it said it took that task
    warm: bool = True  # False until it has imported what it was told to (PRELOAD)


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
        self._pool: list[_Worker] | None = None  # None: no worker started (or all stopped)
        self._failed_starts = 0
        self._no_workers = False  # no worker process could be started here
        self._last_problem = ""

    @property
    def slots(self) -> int:
        return self.workers

    def map(
        self, fn: Callable[[Any], R], items: Sequence[Any], *, here: bool = False
    ) -> Iterator[TaskOutcome[R]]:
        """Yield one outcome per item as it finishes (here, in order, for a small batch).

        `here`: this process runs tasks too, the next one whenever it is free (while the
        workers start, and whenever they are all busy), so the batch never waits for a
        worker's start; one worker fewer is started (this process is one of the `slots`),
        and each gets tasks only once it has imported `fn`'s module. Only for functions that
        cannot bring the process down: a task run here that crashes ends the caller. Not with
        forked workers (a thread of this process would be forked with them).
        """
        refuse_in_worker_start()
        small = len(items) < self.min_items and self._pool is None
        if not items or self.workers < 2 or small or self._no_workers:
            yield from LocalExecutor().map(fn, items)
            return
        if self.start == "fork":
            self.close()  # workers forked for another map hold its items
            self._inherited, here = (fn, items), False
        pool = self._pool = self._pool or []
        todo = deque(range(len(items)))
        size = min(self.workers - 1 if here else self.workers, len(items))
        preload = _modules(fn) if here else ()
        mine = HereTasks(fn, items) if here else None
        try:
            # a worker still importing is waited for even when this process did every task:
            # its start may fail in a way the caller must hear (a script without the
            # `__main__` guard), whichever finished first
            while (
                todo or any(w.task is not None or not w.warm for w in pool) or (mine and mine.busy)
            ):
                self._grow(size, todo, preload)
                if not pool:  # no worker can start: the rest here
                    if mine is not None and mine.busy:
                        yield mine.finish()
                    self._give_up()
                    yield from _here(fn, items, todo)
                    return
                yield from self._feed(todo, fn, items)
                if mine is not None and not mine.busy:
                    mine.start(todo)
                waiting = [w.conn for w in pool] + [w.process.sentinel for w in pool]
                if mine is not None and mine.busy:
                    waiting.append(mine.reader)
                elif not any(w.task is not None or not w.warm for w in pool):
                    continue  # every send failed: those workers are gone, start others
                ready = wait(waiting)
                news = [w for w in pool if w.conn in ready or w.process.sentinel in ready]
                done = [o for worker in news for o in self._hear(worker, todo)]
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
        first, so that they start while this process does something else (its own imports);
        they are stopped at once by `close` if no task came."""
        refuse_in_worker_start()
        if self.workers < 2 or self._no_workers or self._pool or self.start == "fork":
            return
        self._pool = []
        self._grow(self.workers - 1, deque([0]), tuple(modules))

    def _grow(self, size: int, todo: deque[int], preload: tuple[str, ...] = ()) -> None:
        """Start workers up to `size` while there are tasks to give them (each told to
        import `preload` first: it gets no task until it has)."""
        pool = self._pool if self._pool is not None else []
        while todo and len(pool) < size and self._failed_starts < MAX_FAILED_STARTS:
            try:
                worker = _start(self.start, self._inherited)
            except OSError as exc:  # no process, pipe or memory to be had
                self._failed_start(describe_error(exc))
                continue
            pool.append(worker)
            if preload:
                worker.warm = False
                with contextlib.suppress(OSError):  # it died: `_lost` hears of it
                    worker.conn.send((PRELOAD, preload))

    def _give_up(self) -> None:
        """No worker could start: say so once; this executor runs its tasks here from now."""
        if not self._no_workers:
            self._no_workers = True
            log.warning(
                "impactlab: warning: cannot start worker processes (%s); running the tasks "
                "here, in one process",
                self._last_problem,
            )

    def _failed_start(self, problem: str) -> None:
        self._failed_starts += 1
        self._last_problem = problem

    def _feed(
        self, todo: deque[int], fn: Callable[[Any], R], items: Sequence[Any]
    ) -> Iterator[TaskOutcome[R]]:
        """Give each idle worker its next task (a task that cannot be pickled fails here)."""
        for worker in list(self._pool or []):
            if worker.task is None and worker.warm and todo:
                yield from self._send(worker, todo, fn, items)

    def _send(
        self, worker: _Worker, todo: deque[int], fn: Callable[[Any], R], items: Sequence[Any]
    ) -> Iterator[TaskOutcome[R]]:
        index = todo.popleft()
        try:  # a forked worker has them already
            payload = None if self._inherited else bytes(ForkingPickler.dumps((fn, items[index])))
        except Exception as exc:  # the function or the item cannot be pickled
            yield TaskOutcome(index, error=describe_error(exc), exception=exc)
            return
        try:
            worker.conn.send((index, payload))
        except ConnectionError:  # the worker is gone: the task waits for another
            todo.appendleft(index)
            yield from self._lost(worker, todo)
            return
        worker.task, worker.started = index, False

    def _hear(self, worker: _Worker, todo: deque[int]) -> Iterator[TaskOutcome[Any]]:
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
            yield from self._lost(worker, todo)
        elif message[0] == READY:
            worker.ready = True
            if worker.warm:  # up (one told to import first is up once it has)
                self._failed_starts = 0
        elif message[0] == PRELOADED:
            worker.warm = True
            self._failed_starts = 0
        elif message[0] == STARTED:
            worker.started = True
        else:
            worker.task = None
            yield TaskOutcome(*message)

    def _lost(self, worker: _Worker, todo: deque[int]) -> Iterator[TaskOutcome[Any]]:
        """A worker died: its started task fails with the reason, one not started waits."""
        worker.process.join()
        code = worker.process.exitcode
        self._drop(worker)
        if not worker.ready and code == EXIT_MAIN_GUARD:
            raise ExecutorError(MAIN_GUARD_HINT)
        if not (worker.ready and worker.warm):  # died while it started or imported
            self._failed_start(death(code))
        if worker.task is None:
            return
        if worker.started:
            yield TaskOutcome(worker.task, error=death(code))
        else:
            todo.appendleft(worker.task)

    def _drop(self, worker: _Worker) -> None:
        if self._pool is not None and worker in self._pool:
            self._pool.remove(worker)
        worker.conn.close()
        worker.process.join()

    def close(self) -> None:
        """Stop the workers (a task still running is stopped with SIGTERM)."""
        pool, self._pool = self._pool or [], None
        for worker in pool:
            with contextlib.suppress(OSError):
                worker.conn.send(None)
            if worker.task is not None:
                worker.process.terminate()
            elif not worker.warm:  # still importing, holding nothing: no need to wait
                worker.process.kill()
        for worker in pool:
            _stop(worker.process, terminate=False)
            worker.conn.close()

    def __enter__(self) -> ProcessExecutor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _start(method: str, inherited: Inherited | None) -> _Worker:
    """Start one worker process (`method`: "spawn" or "fork", with `inherited` in its memory)
    and connect to it."""
    fork = method == "fork"
    context = multiprocessing.get_context("fork") if fork else multiprocessing.get_context("spawn")
    here, there = context.Pipe()
    sys.stdout.flush()  # a forked worker would write what is buffered here again
    sys.stderr.flush()
    process = context.Process(
        target=serve, args=(there, os.getpid(), inherited), name="impactlab-worker", daemon=True
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


def _here(
    fn: Callable[[Any], R], items: Sequence[Any], todo: deque[int]
) -> Iterator[TaskOutcome[R]]:
    """The tasks left in `todo` run in this process."""
    left = list(todo)
    todo.clear()
    for outcome in LocalExecutor().map(fn, [items[i] for i in left]):
        yield dataclasses.replace(outcome, index=left[outcome.index])


def _modules(fn: Callable[..., Any]) -> tuple[str, ...]:
    """The module a worker imports to run `fn` (a function or a `functools.partial` of one)."""
    module = getattr(getattr(fn, "func", fn), "__module__", None)
    return (module,) if isinstance(module, str) and module != "__main__" else ()
