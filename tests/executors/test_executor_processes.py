"""The processes executor: the same results as the local one, spread over worker processes."""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys

import paths
import polars as pl
import pytest
from polars.testing import assert_frame_equal

from impactlab.analyze.job import run_analysis
from impactlab.executors.choose import make_executor
from impactlab.executors.processes import ProcessExecutor

pytestmark = pytest.mark.slow  # spawned worker processes

GOLDEN = paths.GOLDEN / "logs"
TABLES = ("runs", "bounces", "collisions", "energy", "phases")


def worker_pid(item: int) -> tuple[int, int]:
    """The item and the process that handled it."""
    return item, os.getpid()


def test_items_run_in_workers_and_a_failure_stays_with_its_item():
    with ProcessExecutor(workers=2, min_items=1) as ex:
        outcomes = sorted(ex.map(math.sqrt, [4.0, -1.0, 9.0]), key=lambda o: o.index)
        pids = {o.value[1] for o in ex.map(worker_pid, list(range(6)))}
    assert [o.value for o in outcomes] == [2.0, None, 3.0]
    assert outcomes[1].error == "ValueError: math domain error"
    assert os.getpid() not in pids


def test_a_small_batch_runs_here_without_workers():
    ex = ProcessExecutor(workers=2)  # default: batches under 8 items run in this process
    outcomes = list(ex.map(worker_pid, [1, 2, 3]))
    assert [o.value for o in outcomes] == [(1, os.getpid()), (2, os.getpid()), (3, os.getpid())]
    assert ex._pool == []


def test_processes_analysis_equals_the_local_one(tmp_path, capsys):
    """Tables, report, files and messages: the same whether the logs are analyzed here or
    by two worker processes (with figures, which the workers draw)."""
    logs = tmp_path / "logs"
    shutil.copytree(GOLDEN, logs)
    (logs / "junk.mcap").write_bytes(b"not an mcap file")
    here = run_analysis([logs], tmp_path / "local")
    local_err = capsys.readouterr().err
    with ProcessExecutor(workers=2, min_items=1) as ex:
        there = run_analysis([logs], tmp_path / "processes", executor=ex)
    assert capsys.readouterr().err == local_err
    assert here.runs.height == len(list(GOLDEN.glob("*.mcap")))
    assert there.failed == here.failed and len(here.failed) == 1
    for name in TABLES:
        assert_frame_equal(getattr(there, name), getattr(here, name))
    for name in TABLES:
        assert_frame_equal(
            pl.read_parquet(tmp_path / "processes" / f"{name}.parquet"),
            pl.read_parquet(tmp_path / "local" / f"{name}.parquet"),
        )
    # the same logs analyzed on this machine in one session: the text is the same
    assert (tmp_path / "processes/report.md").read_text() == (
        tmp_path / "local/report.md"
    ).read_text()
    assert [p.relative_to(tmp_path / "processes") for p in there.files] == [
        p.relative_to(tmp_path / "local") for p in here.files
    ]
    assert any(p.suffix == ".png" for p in there.files)


def test_the_command_line_analyzes_in_processes_by_default(tmp_path):
    assert make_executor("processes").name == "processes"
    help_text = subprocess.run(
        [sys.executable, "-m", "impactlab", "analyze", "--help"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "default: processes" in " ".join(help_text.split())
