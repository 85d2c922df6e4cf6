"""The Python API: docs/python-api.md's example runs as written; nothing prints unless asked."""

from __future__ import annotations

import inspect
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from paths import ROOT

import impactlab

DOC = ROOT / "docs" / "python-api.md"


def _examples() -> list[str]:
    return re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)


NEEDS_NOTEBOOK = "notebook=True"  # the `notebook` extra's examples: test_the_notebook_example_runs


def _run(example: str, script: Path) -> subprocess.CompletedProcess[str]:
    script.write_text(example)
    return subprocess.run(
        [sys.executable, str(script)],
        cwd=script.parent,
        capture_output=True,
        text=True,
        timeout=600,
    )


@pytest.mark.slow
def test_the_documented_example_runs(tmp_path):
    example, *others = _examples()
    shutil.copytree(ROOT / "experiments", tmp_path / "experiments")
    out = _run(example, tmp_path / "example.py")
    assert out.returncode == 0, out.stderr
    assert "analyzed, 0 failed; report: results/report.md" in out.stdout
    assert (tmp_path / "results" / "report.md").is_file()
    assert len(list((tmp_path / "replays").glob("*.rrd"))) == 2
    shorter = [other for other in others if NEEDS_NOTEBOOK not in other]
    assert shorter, "docs/python-api.md has no example beside the first and the notebook's"
    for i, other in enumerate(shorter):  # the shorter examples further down run as well
        out = _run(other, tmp_path / f"example{i + 1}.py")
        assert out.returncode == 0, out.stderr


@pytest.mark.slow
@pytest.mark.extras
def test_the_notebook_example_runs(tmp_path):
    """The examples that need the `notebook` extra run as written once it is installed."""
    examples = [example for example in _examples() if NEEDS_NOTEBOOK in example]
    assert examples, f"docs/python-api.md has no example with {NEEDS_NOTEBOOK}"
    shutil.copytree(ROOT / "experiments", tmp_path / "experiments")
    for i, example in enumerate(examples):
        out = _run(example, tmp_path / f"notebook{i}.py")
        assert out.returncode == 0, out.stderr
        assert (tmp_path / "free_fall.rrd").stat().st_size > 0


@pytest.mark.slow
def test_nothing_prints_unless_asked(tmp_path, capfd):
    spec = tmp_path / "drop.toml"
    shutil.copy(ROOT / "experiments" / "free_fall.toml", spec)
    overrides = ["stop.max_time=0.2"]
    runs = impactlab.record(spec, out=tmp_path / "logs", overrides=overrides)
    result = impactlab.analyze(runs.paths, out=tmp_path / "results", figures=True, report=True)
    impactlab.replay(runs.paths, out=tmp_path / "replays")
    assert capfd.readouterr() == ("", "")
    assert result.runs.height == 1
    again = impactlab.record(spec, out=tmp_path / "logs", overrides=overrides, verbose=True)
    assert again[0].status == "reused"
    assert "reused 1 complete log(s)" in capfd.readouterr().out


def test_stage_functions_are_plain_functions():
    """`impactlab.record` and the others are the functions, also once a module of their
    package was imported (which would set the package as the attribute)."""
    import impactlab.analyze.measure.energy  # a module of the stage still imports
    import impactlab.record.spec
    import impactlab.replay.convert

    for name in ("record", "analyze", "replay", "plan"):
        function = getattr(impactlab, name)
        assert inspect.isfunction(function), name
        assert function is getattr(sys.modules[function.__module__], name)
    assert "overrides" in str(inspect.signature(impactlab.record))
    assert impactlab.record.__module__ == "impactlab.record"


def test_a_spec_document_records_like_its_file(tmp_path):
    doc = {
        "name": "tiny",
        "bodies": {"ball": {"radius": 0.05, "mass": 0.2, "pos": [0.0, 0.0, 0.3]}},
        "stop": {"max_time": 0.05},
    }
    (run,) = impactlab.record(doc, out=tmp_path)
    log = impactlab.load(run.path)
    assert log.meta["experiment"] == "tiny" and log.meta["source"] == "<python>"
    assert log.bodies["ball"].height == 26  # 0.05 s at the default 2 ms step, both ends


@pytest.mark.parametrize("given", ["nosuch/", "nosuch.mcap", "logs/*.mcap", "not-a-log.txt"])
def test_analyze_and_replay_of_no_log_create_nothing(tmp_path, monkeypatch, given):
    """Inputs that name no log are a mistake (`NoLogs`, exit code 2 on the command line), said
    before any output folder is made, as the command line says it."""
    from impactlab.logs.inputs import NoLogs

    monkeypatch.chdir(tmp_path)
    (tmp_path / "logs").mkdir()
    (tmp_path / "not-a-log.txt").write_text("text")
    with pytest.raises(NoLogs, match=r"nosuch|matches no file|not an MCAP file"):
        impactlab.analyze(given, out=tmp_path / "out" / "results", figures=True, report=True)
    with pytest.raises(NoLogs):
        impactlab.replay(given, out=tmp_path / "out" / "replays")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["logs", "not-a-log.txt"]
