"""Pick an executor by name ("local", "processes" or "ray"), checked before any work starts."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from impactlab.executors.base import Executor, ExecutorError, LocalExecutor

EXECUTORS = ("local", "processes", "ray")
RAY_INSTALL_HINT = "pip install 'impactlab[ray]'"


def make_executor(name: str = "local", address: str | None = None) -> Executor:
    """The executor called `name` ("local", "processes" or "ray"; `address` is Ray's),
    checked before any work starts (nothing is started here).

    Raises:
        ExecutorError: unknown name, an address for the local executor, or Ray is not
            installed (the message says how to install it).
    """
    if name not in EXECUTORS:
        raise ExecutorError(f"unknown executor {name!r}; choose one of {', '.join(EXECUTORS)}")
    if name != "ray" and address:
        raise ExecutorError("--address applies to --executor ray")
    if name == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise ExecutorError(
                f"--executor ray needs Ray, which is not installed: {RAY_INSTALL_HINT}"
            ) from None
        from impactlab.executors.ray import RayExecutor

        return RayExecutor(address=address)
    if name == "processes":
        from impactlab.executors.processes import ProcessExecutor, refuse_in_worker_start

        refuse_in_worker_start()  # a script without the __main__ guard, imported by a worker
        return ProcessExecutor()
    return LocalExecutor()


@contextlib.contextmanager
def executor_for(executor: Executor | str | None) -> Iterator[Executor | None]:
    """The executor to use: `executor` itself, or one made from its name and closed after."""
    if not isinstance(executor, str):
        yield executor
        return
    made = make_executor(executor)
    try:
        yield made
    finally:
        made.close()
