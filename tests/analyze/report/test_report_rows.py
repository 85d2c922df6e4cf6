"""The report shows at most REPORT_ROWS rows of a table and sentences of a list, then says how
many more there are and which file holds them all; the answers still cover every run."""

from __future__ import annotations

import json

import paths
import polars as pl
import pytest

from impactlab.analyze.job import run_analysis
from impactlab.analyze.report import markdown
from impactlab.analyze.report.markdown import bullets, md_table


def test_a_long_table_is_cut_with_its_count_and_file(monkeypatch):
    monkeypatch.setattr(markdown, "REPORT_ROWS", 3)
    frame = pl.DataFrame({"run": [f"r{i}" for i in range(7)], "x": [float(i) for i in range(7)]})
    lines = md_table(frame, source="`runs.parquet`").splitlines()
    assert [line.split(" | ")[0] for line in lines[2:5]] == ["| r0", "| r1", "| r2"]
    assert lines[-1] == "_The first 3 of 7 rows; all of them are in `runs.parquet`._"
    assert not any("r3" in line for line in lines)
    short = md_table(frame.head(3), source="`runs.parquet`")
    assert "The first" not in short and short.count("\n") == 5  # header, rule, 3 rows


def test_a_long_list_is_cut_with_its_count_and_file(monkeypatch):
    monkeypatch.setattr(markdown, "REPORT_ROWS", 2)
    said = list(bullets((f"s{i}" for i in range(5)), source="`summary.json`", none="- none"))
    assert said == [
        "- s0",
        "- s1",
        "- The first 2 of 5 are above; all of them are in `summary.json`.",
    ]
    assert list(bullets(["a", "b"], source="x", none="- none")) == ["- a", "- b"]
    assert list(bullets([], source="x", none="- none")) == ["- none"]


@pytest.mark.slow
def test_the_report_of_many_runs_lists_some_and_answers_for_all(tmp_path, monkeypatch):
    """The golden logs (drops, collisions, a box) with REPORT_ROWS = 2: each long table and
    list is cut, report.html shows the same lines, the headline and summary.json count
    every run."""
    logs = sorted((paths.GOLDEN / "logs").glob("*.mcap"))
    monkeypatch.setattr(markdown, "REPORT_ROWS", 2)
    result = run_analysis(logs, tmp_path / "out", figures=False)
    n = result.runs.height
    assert result.exit_code == 0 and n == len(logs) > 2
    text = (tmp_path / "out" / "report.md").read_text()
    assert f"_The first 2 of {n:,} rows; all of them are in `runs.parquet`._" in text
    grounded = result.runs["ground"].sum()
    assert f"Over {grounded} run(s) with a ground" in text  # the headline counts them all
    html = (tmp_path / "out" / "report.html").read_text()
    assert f"The first 2 of {n:,} rows; all of them are in" in html
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert len(summary["runs"]) == n
    assert len(summary["answers"]["energy"]) == grounded
    if grounded > 2:
        assert f"- The first 2 of {grounded:,} are above; all of them are in `summary.json`" in text
