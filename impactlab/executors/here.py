"""The tasks the processes executor runs in this process itself (`ProcessExecutor.map(...,
here=True)`): one at a time, on a thread, so that the executor's loop goes on feeding its
workers while this process works."""

from __future__ import annotations

import multiprocessing
import os
import threading
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any, Generic, TypeVar

from impactlab.executors.base import TaskOutcome, describe_error
from impactlab.executors.workers import TEST_SIGKILL_TASK

R = TypeVar("R")


class HereTasks(Generic[R]):
    """The tasks this process runs itself (`map(..., here=True)`), one at a time on a
    thread, so that the loop goes on feeding the workers meanwhile; `reader` is ready when
    the task is done."""

    def __init__(self, fn: Callable[[Any], R], items: Sequence[Any]) -> None:
        self.fn, self.items = fn, items
        self.reader, self._writer = multiprocessing.Pipe(duplex=False)
        self._thread: threading.Thread | None = None
        self._outcome: TaskOutcome[R] | None = None
        self._index = -1

    @property
    def busy(self) -> bool:
        return self._thread is not None

    def start(self, todo: deque[int]) -> None:
        """Take the next task of `todo` and start it (never the one the tests have a
        worker kill itself on, `TEST_SIGKILL_TASK`: that one waits for a worker)."""
        skip = os.environ.get(TEST_SIGKILL_TASK)
        index = next((i for i in todo if str(i) != skip), None)
        if index is None:
            return
        todo.remove(index)
        self._index = index
        self._thread = threading.Thread(target=self._run, name="impactlab-here", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        index = self._index
        try:
            self._outcome = TaskOutcome(index, value=self.fn(self.items[index]))
        except BaseException as exc:  # told to the loop as the task's failure
            caught = exc if isinstance(exc, Exception) else None
            self._outcome = TaskOutcome(index, error=describe_error(exc), exception=caught)
        finally:
            self._writer.send_bytes(b"")

    def finish(self) -> TaskOutcome[R]:
        """Wait for the task started here and take its outcome."""
        self.reader.recv_bytes()
        if self._thread is not None:
            self._thread.join()
        outcome, self._outcome, self._thread = self._outcome, None, None
        return outcome or TaskOutcome(self._index, error="the task gave no outcome")

    def close(self) -> None:
        """Release the pipe (a task still running here finishes on its own; its outcome is
        dropped)."""
        if self._thread is None:
            self.reader.close()
            self._writer.close()
