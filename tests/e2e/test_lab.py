"""`impactlab lab` end to end on a small experiments folder: logs, report, linked replays."""

from __future__ import annotations

import io
import json
from pathlib import Path

import polars as pl
import pytest
from polars.testing import assert_frame_equal
from specs import DIRECT, collision, drop, toml

from impactlab.cli import main

pytestmark = pytest.mark.slow  # the whole lab

DROP = toml(drop("tiny_drop", z=0.5, timestep=0.0005, contact=DIRECT, max_time=2.0, bounces=2))
COLLISION = toml(collision("tiny_collision", timestep=0.0001))


def test_lab_records_analyzes_and_links_replays(tmp_path, capsys):
    experiments = tmp_path / "experiments"
    experiments.mkdir()
    (experiments / "tiny_drop.toml").write_text(DROP)
    (experiments / "tiny_collision.toml").write_text(COLLISION)
    out = tmp_path / "lab"
    args = ["lab", "--experiments", str(experiments), "-o", str(out)]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert printed.strip().splitlines()[-1] == f"report: {out / 'results' / 'report.md'}"
    logs = sorted((out / "logs").glob("*.mcap"))
    assert [p.name.split("-")[0] for p in logs] == ["tiny_collision", "tiny_drop"]
    report = (out / "results" / "report.md").read_text()
    for section in ("## Step 1: Is energy", "## Step 2: Is e constant", "## Step 3: Is momentum"):
        assert section in report
    appendix = (out / "results" / "report-appendix.md").read_text()
    replays = sorted((out / "results" / "replays").glob("*.rrd"))
    assert [p.stem for p in replays] == [p.stem for p in logs]
    for p in replays:
        assert f"(replays/{p.name})" in appendix
    # a second run into the same folder reuses every log and gives the same report and tables
    first = _outputs(out)
    assert main(args) == 0
    assert "reused 2 complete log(s)" in capsys.readouterr().out
    again = _outputs(out)
    assert sorted(again) == sorted(first)
    assert again["results/report.md"] == first["results/report.md"]
    assert json.loads(again["results/summary.json"]) == json.loads(first["results/summary.json"])
    for name in (n for n in first if n.endswith(".parquet")):
        assert_frame_equal(
            pl.read_parquet(out / name), pl.read_parquet(io.BytesIO(first[name])), rel_tol=1e-12
        )
    for log in logs:  # reused, not recorded again
        assert again[f"logs/{log.name}"] == first[f"logs/{log.name}"]


def _outputs(folder: Path) -> dict[str, bytes]:
    """Every file under `folder` by relative path (replays excepted: Rerun stamps them)."""
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in folder.rglob("*")
        if p.is_file() and p.suffix != ".rrd" and p.name != ".impactlab-analysis.lock"
    }


def test_lab_without_specs_is_one_line(tmp_path, capsys):
    assert main(["lab", "--experiments", str(tmp_path), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no experiment specs" in err[0]
    assert not Path(tmp_path / "o").exists()


def test_lab_with_the_calibration_puts_its_table_in_the_appendix(tmp_path, monkeypatch, capsys):
    """`impactlab lab --calibration` (the calibration experiment cut to one run here)."""
    import impactlab.calibrate.job as job

    one = drop("one_impact", z=0.10013, vel=[0.0, 0.0, -2.0], timestep=1e-5, max_time=0.02)
    monkeypatch.setattr(
        job, "calibration_specs", lambda: [{**one, "contact": {"restitution": 0.7}}]
    )
    experiments = tmp_path / "experiments"
    experiments.mkdir()
    (experiments / "tiny_drop.toml").write_text(DROP)
    out = tmp_path / "lab"
    args = ["lab", "--experiments", str(experiments), "-o", str(out), "--no-replay"]
    assert main([*args, "--calibration"]) == 0
    appendix = (out / "results" / "report-appendix.md").read_text()
    section = appendix.split("## Calibration: e against its target at every impact")[1]
    assert "every impact meets its bound" in section
    assert "](calibration/results/calibration.parquet)" in section
    row = next(line for line in section.splitlines() if line.startswith("| one_impact-"))
    assert "| plane/ball | 1 | 0.700 |" in row and row.endswith("| yes |  |")
    assert (out / "results" / "calibration" / "results" / "report.md").is_file()
