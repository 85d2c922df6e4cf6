"""The processes executor: items spread over worker processes on this machine.

Workers are spawned (not forked: polars and MuJoCo run thread pools, which a fork would copy
in whatever state they are), so each pays the import of what its function needs once (about
half a second); a batch smaller than `min_items` therefore runs here, one item after the
other, as the local executor would, unless the workers are up already. Functions and items
must be picklable (module-level functions, plain data), as for Ray.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

from impactlab.executors.base import (
    PROCESS_MIN_ITEMS,
    LocalExecutor,
    TaskOutcome,
    describe_error,
)

R = TypeVar("R")


def available_cpus() -> int:
    """The CPUs this process may run on (its affinity mask, else the machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _timed(fn: Callable[[Any], R], item: Any) -> tuple[R, float]:
    """Run `fn(item)` in a worker; its value and wall time."""
    start = time.perf_counter()
    return fn(item), time.perf_counter() - start


class ProcessExecutor:
    """Items over `workers` spawned processes (default: one per available CPU)."""

    name = "processes"

    def __init__(self, workers: int | None = None, min_items: int = PROCESS_MIN_ITEMS) -> None:
        self.workers = max(1, workers or available_cpus())
        self.min_items = min_items
        self._pool: ProcessPoolExecutor | None = None

    @property
    def slots(self) -> int:
        return self.workers

    def map(self, fn: Callable[[Any], R], items: Sequence[Any]) -> Iterator[TaskOutcome[R]]:
        """Yield one outcome per item as it finishes (here, in order, for a small batch)."""
        if self.workers < 2 or (len(items) < self.min_items and self._pool is None):
            yield from LocalExecutor().map(fn, items)
            return
        pool = self._start(min(self.workers, len(items)))
        futures: dict[Future, int] = {pool.submit(_timed, fn, it): i for i, it in enumerate(items)}
        try:
            while futures:
                done, _ = wait(futures, return_when=FIRST_COMPLETED)
                for future in done:
                    i = futures.pop(future)  # its value is freed once the caller drops it
                    yield self._outcome(future, i)
                del done
        finally:
            for future in futures:
                future.cancel()

    @staticmethod
    def _outcome(future: Future, i: int) -> TaskOutcome:
        try:
            value, wall = future.result()
        except BrokenProcessPool:
            return TaskOutcome(i, error="a worker process died (killed or out of memory)")
        except Exception as exc:  # one failed item never stops the others
            return TaskOutcome(i, error=describe_error(exc))
        return TaskOutcome(i, value=value, wall_s=wall)

    def _start(self, workers: int) -> ProcessPoolExecutor:
        if self._pool is None:
            context = multiprocessing.get_context("spawn")
            self._pool = ProcessPoolExecutor(max_workers=workers, mp_context=context)
        return self._pool

    def close(self) -> None:
        """Stop the workers (cancelling what has not started)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __enter__(self) -> ProcessExecutor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
