"""The report of many runs: its tables show at most REPORT_ROWS rows, then say how many more
there are and which file holds them all; the answers still count every run."""

from __future__ import annotations

import json

import paths
import pytest

from impactlab.analyze.job import run_analysis
from impactlab.analyze.report import blocks, questions


@pytest.mark.slow
def test_the_report_of_many_runs_lists_some_and_answers_for_all(tmp_path, monkeypatch):
    """The golden logs (drops, collisions, a box) with REPORT_ROWS = 2 and MAIN_ROWS = 2: each
    long table is cut, in both pages, and the answers and summary.json count every run."""
    logs = sorted((paths.GOLDEN / "logs").glob("*.mcap"))
    monkeypatch.setattr(blocks, "REPORT_ROWS", 2)
    monkeypatch.setattr(questions, "MAIN_ROWS", 2)
    result = run_analysis(logs, tmp_path / "out", figures=False)
    n = result.runs.height
    assert result.exit_code == 0 and n == len(logs) > 2
    out = tmp_path / "out"
    for page in ("report-appendix.md", "report-appendix.html"):
        assert (
            f"The first 2 of {n:,} rows; all of them are in runs.parquet."
            in (out / page).read_text()
        )
    report = (out / "report.md").read_text()
    assert f"The first 2 of {n} rows; all of them are in [the appendix]" in report  # Step 1
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["runs"]) == n
    assert set(summary["answers"]) == {"energy", "restitution", "collision", "parameter_study"}
