"""The public API is typed for a type checker: mypy (strict) on a script using it.

The script that uses the API as documented type-checks with no error, every call's result
has its exact type (`assert_type`: no Any), and it runs; the same calls with a misspelt
keyword (`figurez=True`), a misspelt function or a wrong argument type are errors.
`impactlab.analyze` stays the function after `import impactlab.analyze`.
"""

from __future__ import annotations

import os
import runpy
import subprocess
import sys

import pytest
from paths import ROOT

pytestmark = pytest.mark.slow  # mypy over the documented use


GOOD = """
from collections.abc import Sequence
from pathlib import Path
from typing import assert_type

import impactlab
import impactlab.analyze
from impactlab.analyze import AnalysisResult
from impactlab.logs import RunLog
from impactlab.record import PlannedRun, RecordResult
from impactlab.tools.diff import LogDiff


def use(spec: Path, out: Path) -> float:
    runs = impactlab.record(spec, out=out / "logs", overrides=["stop.max_time=1"])
    assert_type(runs, RecordResult)
    assert_type(impactlab.plan(spec), Sequence[PlannedRun])
    result = impactlab.analyze(runs.paths, out=out / "results", report=True)
    assert_type(result, AnalysisResult)
    assert_type(impactlab.replay(runs.paths, out=out / "replays"), list[Path])
    log = impactlab.load(runs[0].path)
    assert_type(log, RunLog)
    same = impactlab.diff(log, runs[0].path, atol=1e-9)
    assert_type(same, LogDiff)
    assert same.equal
    return float(result.runs.height)
"""

BAD = """
import impactlab
import impactlab.analyze

impactlab.analyze(["logs"], figurez=True)
impactlab.record("drop.toml", overides=["ball.mass=2"])
impactlab.recrod("drop.toml")
impactlab.replay(["logs"], out=3)
"""


@pytest.fixture(scope="module")
def mypy_output(tmp_path_factory) -> dict[str, list[str]]:
    """mypy's error lines per snippet, one run over both (this checkout's impactlab)."""
    where = tmp_path_factory.mktemp("typing")
    (where / "good.py").write_text(GOOD)
    (where / "bad.py").write_text(BAD)
    env = {**os.environ, "MYPYPATH": str(ROOT)}
    config = ["--config-file", str(ROOT / "pyproject.toml"), "--cache-dir", str(where / "cache")]
    done = subprocess.run(
        [sys.executable, "-m", "mypy", *config, "good.py", "bad.py"],
        cwd=where,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode in (0, 1), done.stdout + done.stderr  # 2: mypy itself failed
    lines = [line for line in done.stdout.splitlines() if ": error:" in line]
    return {name: [x for x in lines if x.startswith(name)] for name in ("good.py", "bad.py")}


def test_documented_use_type_checks_with_exact_types(mypy_output):
    assert mypy_output["good.py"] == []


def test_mistakes_are_type_errors(mypy_output):
    errors = "\n".join(mypy_output["bad.py"])
    assert 'bad.py:5: error: Unexpected keyword argument "figurez" for "analyze"' in errors
    assert 'bad.py:6: error: Unexpected keyword argument "overides" for "record"' in errors
    assert 'bad.py:7: error: Module has no attribute "recrod"' in errors
    assert 'bad.py:8: error: No overload variant of "replay" matches argument types' in errors
    assert len(mypy_output["bad.py"]) == 4


def test_the_type_checked_script_runs(tmp_path, monkeypatch):
    """The typed calls work as typed: a 1 s free fall recorded, analyzed, replayed, loaded,
    and compared with itself (`impactlab.diff`)."""
    script = tmp_path / "good.py"
    script.write_text(GOOD)
    use = runpy.run_path(str(script))["use"]
    assert use(ROOT / "experiments" / "free_fall.toml", tmp_path) == 1.0
