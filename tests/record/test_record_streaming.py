"""Long runs: rows are streamed into the log chunk by chunk, so memory does not grow with the
run's length, and SIGTERM stops a job within a chunk, leaving only complete logs."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
from paths import ROOT
from specs import drop, toml
from waiting import interrupt, record_process, wait_until

from impactlab.logs.load import load_log

PEAK = """
import json, sys
from pathlib import Path
from impactlab.record import plan, record_runs
runs = plan([sys.argv[1]])
(result,) = record_runs(runs, Path(sys.argv[2]))
hwm = [l for l in Path("/proc/self/status").read_text().splitlines() if l.startswith("VmHWM:")]
print(json.dumps({"peak_mb": int(hwm[0].split()[1]) / 1024, "logged": result.logged}))
"""


def long_drop(max_time: float, **options) -> str:
    """A ball dropped from 1 m at a 0.1 ms step for `max_time` s, as TOML."""
    return toml(drop("long", timestep=0.0001, max_time=max_time, **options))


def _peak(tmp_path: Path, max_time: float) -> dict:
    spec = tmp_path / f"long_{max_time:g}.toml"
    spec.write_text(long_drop(max_time))
    out = subprocess.run(
        [sys.executable, "-c", PEAK, str(spec), str(tmp_path / f"logs_{max_time:g}")],
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_memory_does_not_grow_with_the_run(tmp_path):
    """A run of 200,001 logged steps peaks within 40 MB of one of 10,001 steps (keeping the
    rows would take about 150 MB more: 200,000 rows of 29 sensor values, then the log's
    arrays made from them)."""
    short = _peak(tmp_path, 1.0)
    long = _peak(tmp_path, 20.0)
    assert (short["logged"], long["logged"]) == (10_001, 200_001)
    assert long["peak_mb"] - short["peak_mb"] < 40, (short, long)


@pytest.mark.slow
def test_sigterm_stops_a_long_run_within_a_chunk(tmp_path):
    """One run of 10^7 steps (about a minute): SIGTERM once its log is being written ends the
    job within seconds, exit 130, and leaves no log and no temporary file."""
    spec = tmp_path / "endless.toml"
    spec.write_text(long_drop(1000.0, every=100))
    out = tmp_path / "logs"
    proc = record_process(spec, out)
    # the log is open: simulation is under way
    wait_until(lambda: any(out.glob("*.partial")), proc, what="a log being written")
    time.sleep(0.5)
    stdout, stderr = interrupt(proc)
    assert proc.returncode == 130, (stdout, stderr)
    assert "Traceback" not in stderr and "impactlab: interrupted" in stderr
    assert list(out.iterdir()) == []


@pytest.mark.slow
def test_a_streamed_log_equals_the_runs_rows(tmp_path):
    """Streaming keeps every row, in order, with the logging stride counted from step 0
    across chunk boundaries (chunks of 5000 steps, logging every 3rd step)."""
    spec = tmp_path / "stride.toml"
    spec.write_text(long_drop(1.5, every=3))
    out = tmp_path / "logs"
    code = subprocess.run(
        [sys.executable, "-m", "impactlab", "record", str(spec), "-o", str(out)], cwd=ROOT
    ).returncode
    assert code == 0
    (path,) = out.glob("*.mcap")
    ball = load_log(path).bodies["ball"]
    steps = ball["t_ns"].to_numpy() // 100_000
    assert steps.tolist() == list(range(0, 15_001, 3))
    assert load_log(path).outcome == "completed"
