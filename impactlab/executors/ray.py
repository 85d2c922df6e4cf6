"""The Ray executor: each work item is one Ray task; a `ray.wait` loop streams the outcomes.

Ray is an optional dependency (`pip install 'impactlab[ray]'`); this module is imported only
when `--executor ray` is asked for, and imports `ray` when an executor is made.

Tasks ask for one CPU each. The function is put in the object store once; each task gets
its item (a few planned runs or one log path) and returns a small value (run summaries or
one run's analysis tables): logs are written to disk by the task, never sent back. At most
4 tasks per CPU of the cluster (at least 16) are in flight, so a sweep of any size keeps the
driver's memory flat. Tasks lost with their worker or node are retried by Ray (`MAX_RETRIES`);
an exception raised by the function is not retried and becomes that item's failure reason.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator, Sequence
from typing import Any, TypeVar

from impactlab.executors.base import ExecutorError, TaskOutcome, describe_error

R = TypeVar("R")

MAX_RETRIES = 2  # retries of a task whose worker or node died


def _call(fn: Callable[[Any], R], item: Any) -> R:
    return fn(item)


class RayExecutor:
    """Runs items as Ray tasks on the cluster at `address` (default: a local Ray instance).

    When Ray is already initialized in this process (e.g. by a test or a notebook), that
    connection is used and left open on `close`.

    `address`: the cluster's `HOST:PORT` (`ray start --head` prints it), or None to start
    Ray on this machine.
    """

    name = "ray"

    def __init__(self, address: str | None = None) -> None:
        import ray

        self._ray = ray
        self.address = address
        self._owns = False
        self._connected = False

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
                kwargs |= {"num_gpus": 0, "include_dashboard": False}
            try:
                ray.init(**kwargs)
            except (ConnectionError, RuntimeError, ValueError) as exc:
                where = self.address or "a local Ray instance"
                problem = describe_error(exc)
                raise ExecutorError(f"cannot start or reach {where}: {problem}") from None
            self._owns = True
        self._connected = True

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
        window = max(16, 4 * self.slots)  # most tasks in flight
        remote = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(_call)
        fn_ref = ray.put(fn)
        pending: dict[Any, int] = {}
        next_item = 0
        try:
            while pending or next_item < len(items):
                while next_item < len(items) and len(pending) < window:
                    pending[remote.remote(fn_ref, items[next_item])] = next_item
                    next_item += 1
                ready, _ = ray.wait(list(pending), num_returns=1)
                for ref in ready:
                    index = pending.pop(ref)
                    yield self._outcome(ref, index)
        finally:
            for ref in pending:  # the driver stopped early (error, Ctrl-C): stop the rest
                ray.cancel(ref, force=True)

    def _outcome(self, ref: Any, index: int) -> TaskOutcome[Any]:
        ray = self._ray
        try:
            value = ray.get(ref)
        except ray.exceptions.RayTaskError as exc:  # the function raised in the task
            cause = getattr(exc, "cause", None)
            return TaskOutcome(index, error=describe_error(cause or exc), exception=cause)
        except ray.exceptions.RayError as exc:  # worker or node lost beyond the retries
            return TaskOutcome(index, error=describe_error(exc))
        return TaskOutcome(index, value=value)

    def close(self) -> None:
        """Shut Ray down if this executor started it."""
        if self._owns and self._ray.is_initialized():
            self._ray.shutdown()
        self._owns = self._connected = False

    def __enter__(self) -> RayExecutor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
