"""The analyze command: outputs, bad inputs (one line each, others still analyzed), exit codes,
and that the analysis stage never imports mujoco."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import polars as pl
import pytest
from known import COLLISION_SPEC, DROP_SPEC
from mcap.writer import Writer
from specs import SOFT, drop, toml

from impactlab.analyze.job import run_analysis
from impactlab.cli import main


@pytest.fixture(scope="module")
def logs(record_spec) -> dict[str, Path]:
    (drop,) = record_spec("known_drop", DROP_SPEC)
    (hit,) = record_spec("known_collision", COLLISION_SPEC)
    (miss,) = record_spec("known_collision_miss", COLLISION_SPEC, overrides=["stop.max_time=0.05"])
    return {"drop": drop, "hit": hit, "miss": miss}


def _not_impactlab_mcap(path: Path) -> Path:
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        schema = w.register_schema("x", "jsonschema", b"{}")
        channel = w.register_channel("/other", "json", schema)
        w.add_message(channel, log_time=0, data=b"{}", publish_time=0)
        w.finish()
    return path


@pytest.mark.slow
def test_outputs_written(logs, tmp_path):
    out = tmp_path / "results"
    result = run_analysis([logs["drop"], logs["hit"], logs["miss"]], out)
    assert result.exit_code == 0
    for name in ("runs", "bounces", "collisions", "energy", "phases"):
        assert pl.read_parquet(out / f"{name}.parquet").height > 0
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["runs"]) == 3
    report = (out / "report.md").read_text()
    for link in report.split("](")[1:]:
        target = link.split(")")[0]
        if target.startswith("#"):  # an in-page link: a heading's GitHub-style slug
            slugs = {
                re.sub(r"[^\w\- ]", "", h.lower()).replace(" ", "-")
                for h in re.findall(r"^#+ (.+)$", report, re.M)
            }
            assert target[1:] in slugs, target
            continue
        assert (out / target.split("#")[0]).is_file(), target  # relative links resolve
    appendix = (out / "report-appendix.md").read_text()
    assert "never happened" in appendix  # the run without a collision is reported, with reason
    pngs = sorted(p.name for p in (out / "figures").glob("*.png"))
    assert any(p.startswith("energy-") for p in pngs)
    assert any(p.startswith("collision-") for p in pngs)
    assert "restitution-vs-speed.png" in pngs


@pytest.mark.slow
def test_bad_inputs(logs, tmp_path, capsys):
    """Found in a folder: not MCAP, truncated, no impactlab channels: one line each; exit 1;
    the rest analyzed (a named input that is missing or no log is exit 2: test_exit_codes.py)."""
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "text.mcap").write_text("hello, not a log\n")
    _not_impactlab_mcap(bad / "other.mcap")
    data = logs["drop"].read_bytes()
    (bad / "truncated.mcap").write_bytes(data[: len(data) // 2])
    out = tmp_path / "results"
    code = main(["analyze", str(bad), str(logs["hit"]), "-o", str(out)])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    err = [line for line in lines if not line.startswith("impactlab: warning: ")]
    assert len(err) == 2, lines
    assert all(line.startswith("impactlab: error: ") for line in err)
    (warning,) = [line for line in lines if line not in err]
    assert "truncated.mcap: partial log" in warning
    assert any("text.mcap" in line and "not an MCAP" in line for line in err)
    assert any("other.mcap" in line and "not an impactlab log" in line for line in err)
    runs = pl.read_parquet(out / "runs.parquet")
    assert runs.height == 2  # the collision and what could be read of the truncated drop
    partial = runs.filter(pl.col("partial"))
    assert partial.height == 1 and partial["file"][0].endswith("truncated.mcap")
    assert partial["duration_s"][0] > 0
    assert "Partial logs" in (out / "report.md").read_text()


def test_unwritable_output(logs, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    code = main(["analyze", str(logs["hit"]), "-o", str(blocker / "results")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("impactlab: error: ")


def test_no_logs_found(tmp_path, capsys):
    """Nothing to analyze is a mistake in the command: one line, exit 2, nothing written."""
    code = main(["analyze", str(tmp_path / "*.mcap"), "-o", str(tmp_path / "r")])
    assert code == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f"impactlab: error: {tmp_path / '*.mcap'}: matches no file"
    ]
    assert not (tmp_path / "r").exists()


@pytest.mark.slow
def test_analysis_does_not_import_mujoco(logs, tmp_path):
    code = (
        "import sys\n"
        "from impactlab.analyze.job import run_analysis\n"
        f"r = run_analysis([{str(logs['drop'])!r}, {str(logs['hit'])!r}], "
        f"__import__('pathlib').Path({str(tmp_path / 'r')!r}))\n"
        "assert r.exit_code == 0\n"
        "bad = sorted(m for m in sys.modules if m == 'mujoco' or m.startswith('mujoco.'))\n"
        "assert not bad, bad\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


NO_BOUNCE_SWEEP = toml(
    drop(
        "early_stop",
        timestep=0.0005,
        contact=SOFT,
        max_time=0.5,
        sweep={"ball.pos": [[0.0, 0.0, 1.0], [0.0, 0.0, 1.1]]},
    )
)


@pytest.mark.slow
def test_sweep_without_a_complete_bounce_still_reports(record_spec, tmp_path):
    """A drop sweep cut before any rebound: the report says so instead of failing."""
    logs = record_spec("early_stop", NO_BOUNCE_SWEEP)
    result = run_analysis(logs, tmp_path / "out")
    assert result.exit_code == 0
    report = (tmp_path / "out" / "report.md").read_text()
    assert "no rebound" in report
    assert result.runs["n_bounces_complete"].to_list() == [0, 0]


def test_no_figures_writes_the_tables_and_no_figure(logs, tmp_path, capsys):
    """`--no-figures` (what batch jobs use): the same tables, a report, no PNG, no image link."""
    out = tmp_path / "tables-only"
    assert (
        main(["analyze", str(logs["drop"]), str(logs["hit"]), "-o", str(out), "--no-figures"]) == 0
    )
    assert pl.read_parquet(out / "runs.parquet").height == 2
    assert pl.read_parquet(out / "bounces.parquet").height > 0
    assert not list(out.rglob("*.png"))
    report = (out / "report.md").read_text()
    assert "![" not in report  # no image link (in-page links stay)
    assert "No figures were drawn (--no-figures)." in report


@pytest.mark.parametrize(("copies", "started"), [(1, False), (7, False), (8, True)])
def test_workers_are_prestarted_only_for_a_batch_they_will_run(
    tmp_path, monkeypatch, copies, started
):
    """A batch below the processes executor's `min_items` (8) runs in this process: starting
    workers for it (one log: 1-2 s of a spawned interpreter's imports) only delays the end."""
    import shutil

    from impactlab.analyze import job
    from impactlab.executors.processes import ProcessExecutor

    golden = Path(__file__).parents[1] / "golden" / "logs" / "drop_bounces.mcap"
    for i in range(copies):
        shutil.copy(golden, tmp_path / f"run{i}.mcap")
    calls: list[object] = []
    monkeypatch.setattr(ProcessExecutor, "prestart", lambda self, modules: calls.append(modules))
    monkeypatch.setattr(job, "run_analysis", lambda *a, **k: type("R", (), {"exit_code": 0})())
    assert main(["analyze", str(tmp_path), "-o", str(tmp_path / "out")]) == 0
    assert bool(calls) is started
