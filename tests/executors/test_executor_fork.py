"""The processes executor with forked workers (the record job's): each map forks its workers
with the function and items in their memory, nothing pickled, and stops them at its end; a
task's exception comes back with its outcome."""

from __future__ import annotations

import os
import sys
import threading

import pytest

from impactlab.executors.processes import ProcessExecutor

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forks on Linux")


class NotPicklable:
    """An item pickle refuses (a lock inside): a forked worker reads it from its memory."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.lock = threading.Lock()


def test_forked_workers_read_unpicklable_functions_and_items_from_their_memory():
    offset = 100
    items = [NotPicklable(i) for i in range(6)]
    with ProcessExecutor(workers=2, min_items=1, start="fork") as ex:
        outcomes = sorted(
            ex.map(lambda x: (x.n + offset, os.getpid()), items), key=lambda o: o.index
        )
        assert ex._pool == []  # the map's workers are stopped with it
        again = list(ex.map(lambda x: x.n * 2, items[:2]))  # new workers, this map's items
    assert [o.value[0] for o in outcomes] == [100 + i for i in range(6)]
    assert os.getpid() not in {o.value[1] for o in outcomes}
    assert sorted(o.value for o in again) == [0, 2]


def test_a_killed_forked_worker_fails_only_its_task():
    def die_on_two(n: int) -> int:
        if n == 2:
            os.kill(os.getpid(), 9)
        return n

    with ProcessExecutor(workers=2, min_items=1, start="fork") as ex:
        outcomes = sorted(ex.map(die_on_two, list(range(5))), key=lambda o: o.index)
    assert [o.value for o in outcomes] == [0, 1, None, 3, 4]
    assert outcomes[2].error == "worker process died (signal SIGKILL)"
    assert outcomes[2].exception is None


class Unpicklable(Exception):
    def __init__(self, a: int, b: int) -> None:  # pickle would call it with one argument
        super().__init__(f"{a} and {b}")


def fail(n: int) -> int:
    if n == 0:
        raise ValueError("zero")
    raise Unpicklable(n, n)


def test_the_exception_comes_back_when_it_pickles():
    with ProcessExecutor(workers=2, min_items=1, start="fork") as ex:
        outcomes = sorted(ex.map(fail, [0, 1]), key=lambda o: o.index)
    assert isinstance(outcomes[0].exception, ValueError) and outcomes[0].error == "ValueError: zero"
    assert outcomes[1].exception is None and outcomes[1].error == "Unpicklable: 1 and 1"
