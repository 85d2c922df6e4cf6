"""The processes executor working in this process too (`map(..., here=True)`, the analysis):
tasks run here while the workers start and in the workers once they are up; the outcomes
and the analysis' files are those of the local executor."""

from __future__ import annotations

import json
import logging
import os
import shutil

import paths
import polars as pl
import pytest
from polars.testing import assert_frame_equal

from impactlab.analyze.job import run_analysis
from impactlab.executors.processes import ProcessExecutor

pytestmark = pytest.mark.slow  # spawned worker processes

TABLES = ("runs", "bounces", "collisions", "energy", "phases")


def worker_pid(item: int) -> tuple[int, int]:
    """The item and the process that handled it."""
    return item, os.getpid()


def warm(ex: ProcessExecutor) -> None:
    """Wait until every prestarted worker has said it imported its modules (READY)."""
    for worker in ex._pool:
        while not worker.ready:
            assert worker.conn.poll(120), "the worker did not start"
            list(ex._hear(worker))


def test_this_process_works_while_the_workers_start():
    """A cold worker gets no task: this process runs the first one itself, and every
    outcome is there once, with its index."""
    with ProcessExecutor(workers=2, min_items=1) as ex:
        outcomes = list(ex.map(worker_pid, list(range(6)), here=True))
        assert len(ex._pool) == 1  # one worker: this process is the other slot
    assert outcomes[0].index == 0 and outcomes[0].value == (0, os.getpid())
    assert sorted(o.value[0] for o in outcomes) == list(range(6))
    assert all(o.ok and o.index == o.value[0] for o in outcomes)


def test_a_warm_worker_takes_tasks_beside_this_process():
    """A worker that imported the function's module (prestart) gets the next task as soon
    as this process has heard it is up; the tasks are shared between the two."""
    with ProcessExecutor(workers=2, min_items=1) as ex:
        ex.prestart([__name__])
        warm(ex)
        outcomes = sorted(ex.map(worker_pid, list(range(4)), here=True), key=lambda o: o.index)
    assert [o.value[0] for o in outcomes] == [0, 1, 2, 3]
    pids = [o.value[1] for o in outcomes]
    assert pids[0] != os.getpid()  # the warm worker was fed before this process took one
    assert pids[1] == os.getpid()


def test_shared_analysis_writes_the_local_files(tmp_path):
    """Tables-only analysis with a warm worker and this process sharing the logs: every
    table, summary.json and report.md equal the local executor's."""
    logs = tmp_path / "logs"
    shutil.copytree(paths.GOLDEN / "logs", logs)
    here = run_analysis([logs], tmp_path / "local", figures=False)
    with ProcessExecutor(workers=2, min_items=1) as ex:
        ex.prestart(["impactlab.analyze.batch"])
        warm(ex)
        shared = run_analysis([logs], tmp_path / "shared", figures=False, executor=ex)
    assert shared.failed == here.failed == []
    for name in TABLES:
        assert_frame_equal(
            pl.read_parquet(tmp_path / "shared" / f"{name}.parquet"),
            pl.read_parquet(tmp_path / "local" / f"{name}.parquet"),
        )
    local_summary = json.loads((tmp_path / "local" / "summary.json").read_text())
    assert json.loads((tmp_path / "shared" / "summary.json").read_text()) == local_summary
    for name in ("report.md",):
        assert (tmp_path / "shared" / name).read_text() == (tmp_path / "local" / name).read_text()


DIES_ON_IMPORT = """
import multiprocessing, os, signal, time

if multiprocessing.parent_process() is not None:  # a worker importing it: killed
    os.kill(os.getpid(), signal.SIGKILL)
EX = None  # the executor under test


def after_three_failed_starts(item):
    deadline = time.monotonic() + 60  # a bound, not a speed requirement
    while EX._failed_starts < 3 and time.monotonic() < deadline:
        time.sleep(0.01)
    return item, os.getpid(), EX._failed_starts
"""


def test_workers_that_die_while_importing_leave_the_tasks_here(tmp_path, monkeypatch, caplog):
    """Workers killed while they import the tasks' module count as failed starts (not
    started again and again): after three, the tasks all run here, with the one warning
    line, and none is lost."""
    (tmp_path / "dies_on_import.py").write_text(DIES_ON_IMPORT)
    monkeypatch.syspath_prepend(str(tmp_path))
    import dies_on_import

    with caplog.at_level(logging.WARNING), ProcessExecutor(workers=2, min_items=1) as ex:
        dies_on_import.EX = ex
        items = list(range(4))
        outcomes = sorted(
            ex.map(dies_on_import.after_three_failed_starts, items, here=True),
            key=lambda o: o.index,
        )
    assert [o.value for o in outcomes] == [(i, os.getpid(), 3) for i in items]
    assert "cannot start worker processes (worker process died (signal SIGKILL))" in caplog.text
