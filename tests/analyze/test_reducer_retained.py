"""What the analysis' driver retains per run: the runs table in a few pieces, whatever the
number of runs (each small frame costs memory besides its data), the same table as one
concatenation of every run's row."""

from __future__ import annotations

from pathlib import Path

import pytest
from polars.testing import assert_frame_equal

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.analyze.tables import combine as tables_module
from impactlab.analyze.tables.combine import TableReducer
from impactlab.logs.load import load_log

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "logs"


@pytest.fixture(scope="module")
def analyses():
    logs = sorted(GOLDEN.glob("*.mcap"))
    assert len(logs) >= 4
    return [analyze_run(load_log(p)) for p in logs]


def test_runs_table_is_kept_in_few_pieces(analyses, monkeypatch):
    monkeypatch.setattr(tables_module, "REDUCE_EVERY", 1)  # a piece per run
    monkeypatch.setattr(tables_module, "RUNS_PIECES", 3)
    taken = [analyses[i % len(analyses)] for i in range(40)]
    reducer, one = TableReducer(), TableReducer()
    for i, a in enumerate(taken):
        reducer.take(a)
        assert len(reducer._runs) < 3, i  # joined before a third piece is kept
    result = reducer.result(None, [])
    monkeypatch.setattr(tables_module, "RUNS_PIECES", 10**9)
    for a in taken:
        one.take(a)
    assert len(one._runs) == 40  # the same runs, never joined
    assert_frame_equal(result.runs, one.result(None, []).runs, check_exact=True)
