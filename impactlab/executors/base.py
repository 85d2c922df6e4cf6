"""Executors: map a function over work items, here or on a cluster.

An executor runs `fn(item)` for each item and yields one `TaskOutcome` per item as it
finishes: its value, or the reason it failed (one item failing never stops the others).
`LocalExecutor` runs the items one after the other in this process (the record-side
functions are multi-threaded themselves); `impactlab.executors.processes.ProcessExecutor`
spreads them over worker processes on this machine; `impactlab.executors.ray.RayExecutor`
runs them as Ray tasks on a cluster. `make_executor("local" | "processes" | "ray", address)`
picks one.

Executors know nothing of recording or analysis: the record tasks live in
`impactlab.record.recorder`, the analysis batch in `impactlab.analyze.batch`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar

from impactlab.errors import ImpactlabError

R = TypeVar("R")

PROCESS_MIN_ITEMS = 8  # the processes executor runs smaller batches here: workers cost more


class ExecutorError(ImpactlabError):
    """The executor cannot be used (Ray missing, cluster unreachable). Exit code 2."""

    exit_code = 2


@dataclass(frozen=True)
class TaskOutcome(Generic[R]):
    """What one item gave: its value, or `error` (the reason) when the task failed, with the
    exception raised (when it could be brought back: None for a lost worker)."""

    index: int
    value: R | None = None
    error: str | None = None
    exception: BaseException | None = None

    @property
    def ok(self) -> bool:
        return self.error is None


class Executor(Protocol):
    """Runs a function over work items; see the module docstring."""

    name: str

    @property
    def slots(self) -> int:
        """How many tasks run at the same time."""
        ...

    def map(self, fn: Callable[[Any], R], items: Sequence[Any]) -> Iterator[TaskOutcome[R]]:
        """Yield one outcome per item, in the order they finish."""
        ...

    def close(self) -> None:
        """Release what the executor started."""
        ...


def describe_error(exc: BaseException) -> str:
    """One line: the exception's type and message."""
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def run_task(fn: Callable[[Any], R], item: Any, index: int) -> TaskOutcome[R]:
    """`fn(item)`'s outcome: its value, or the exception it raised (one failed item never
    stops the others)."""
    try:
        return TaskOutcome(index, value=fn(item))
    except Exception as exc:
        return TaskOutcome(index, error=describe_error(exc), exception=exc)


class LocalExecutor:
    """Items one after the other in this process (the functions use threads themselves)."""

    name = "local"
    slots = 1

    def map(self, fn: Callable[[Any], R], items: Sequence[Any]) -> Iterator[TaskOutcome[R]]:
        for i, item in enumerate(items):
            yield run_task(fn, item, i)

    def close(self) -> None:
        pass
