"""The Ray executor: each work item is one Ray task; a `ray.wait` loop streams the outcomes.

Ray is an optional dependency (`pip install 'impactlab[ray]'`); this module is imported only
when `--executor ray` is asked for, and imports `ray` when an executor is made.

Tasks ask for one CPU each. The function is put in the object store once; each task gets
its item (a few planned runs or one log path) and returns a small value (run summaries or
one run's analysis tables): logs are written to disk by the task, never sent back. At most
`window` tasks are in flight, so a sweep of any size keeps the driver's memory flat. Tasks
lost with their worker or node are retried by Ray (`max_retries`); an exception raised by
the function is not retried and becomes that item's failure reason.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any, TypeVar

from impactlab.executors.base import ExecutorError, TaskOutcome, describe_error

R = TypeVar("R")

MAX_RETRIES = 2  # retries of a task whose worker or node died


def _call(fn: Callable[[Any], R], item: Any) -> tuple[R, float]:
    start = time.perf_counter()
    value = fn(item)
    return value, time.perf_counter() - start


class RayExecutor:
    """Runs items as Ray tasks on the cluster at `address` (default: a local Ray instance).

    When Ray is already initialized in this process (e.g. by a test or a notebook), that
    connection is used and left open on `close`.

    Args:
        address: the cluster's `HOST:PORT` (`ray start --head` prints it), or None to start
            Ray on this machine.
        num_cpus, object_store_memory: for a Ray instance started here.
        max_retries: retries of a task lost with its worker or node.
        window: most tasks in flight (default: 4 per CPU of the cluster, at least 16).
    """

    name = "ray"

    def __init__(
        self,
        address: str | None = None,
        *,
        num_cpus: int | None = None,
        object_store_memory: int | None = None,
        max_retries: int = MAX_RETRIES,
        window: int | None = None,
    ) -> None:
        import ray

        self._ray = ray
        self.address = address
        self._init_kwargs = {"num_cpus": num_cpus, "object_store_memory": object_store_memory}
        self._owns = False
        self._connected = False
        self.max_retries = max_retries
        self._window = window

    def _connect(self) -> None:
        """Start or join Ray on first use (a sweep with nothing to do never starts it)."""
        if self._connected:
            return
        ray = self._ray
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {"logging_level": logging.WARNING}
            if self.address:
                kwargs["address"] = self.address
            else:
                kwargs |= {**self._init_kwargs, "num_gpus": 0, "include_dashboard": False}
            try:
                ray.init(**kwargs)
            except (ConnectionError, RuntimeError, ValueError) as exc:
                where = self.address or "a local Ray instance"
                problem = describe_error(exc)
                raise ExecutorError(f"cannot start or reach {where}: {problem}") from None
            self._owns = True
        self._connected = True

    @property
    def window(self) -> int:
        """Most tasks in flight."""
        return self._window or max(16, 4 * self.slots)

    @property
    def slots(self) -> int:
        """CPUs in the cluster (one task per CPU)."""
        self._connect()
        resources = self._ray.cluster_resources()  # type: ignore[no-untyped-call]  # ray: no hints
        return max(1, int(resources.get("CPU", 1)))

    def map(self, fn: Callable[[Any], R], items: Sequence[Any]) -> Iterator[TaskOutcome[R]]:
        """Yield one outcome per item as its task finishes."""
        self._connect()
        ray = self._ray
        window = self.window
        remote = ray.remote(num_cpus=1, max_retries=self.max_retries)(_call)
        fn_ref = ray.put(fn)
        pending: dict[Any, int] = {}
        started: dict[int, float] = {}
        next_item = 0
        try:
            while pending or next_item < len(items):
                while next_item < len(items) and len(pending) < window:
                    pending[remote.remote(fn_ref, items[next_item])] = next_item
                    started[next_item] = time.perf_counter()
                    next_item += 1
                ready, _ = ray.wait(list(pending), num_returns=1)
                for ref in ready:
                    index = pending.pop(ref)
                    yield self._outcome(ref, index, time.perf_counter() - started.pop(index))
        finally:
            for ref in pending:  # the driver stopped early (error, Ctrl-C): stop the rest
                ray.cancel(ref, force=True)

    def _outcome(self, ref: Any, index: int, elapsed: float) -> TaskOutcome[Any]:
        ray = self._ray
        try:
            value, wall_s = ray.get(ref)
        except ray.exceptions.RayTaskError as exc:  # the function raised in the task
            cause = getattr(exc, "cause", None)
            return TaskOutcome(
                index, error=describe_error(cause or exc), wall_s=elapsed, exception=cause
            )
        except ray.exceptions.RayError as exc:  # worker or node lost beyond the retries
            return TaskOutcome(index, error=describe_error(exc), wall_s=elapsed)
        return TaskOutcome(index, value=value, wall_s=wall_s)

    def close(self) -> None:
        """Shut Ray down if this executor started it."""
        if self._owns and self._ray.is_initialized():
            self._ray.shutdown()
        self._owns = self._connected = False

    def __enter__(self) -> RayExecutor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
