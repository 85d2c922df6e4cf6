"""Peak memory of analyzing one large log, measured in a fresh process (see docs/reliability.md).

The bound is loose on purpose: it catches a regression that copies the decoded data many
times over, not a few percent.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from specs import drop, toml

from impactlab.record import plan, record_runs

pytestmark = pytest.mark.slow  # peak memory of a 100,000-step analysis


MEASURE = r"""
import json, sys, time
import impactlab.analyze.job, impactlab.cli  # the imports are the baseline
from impactlab.logs.load import load_log
from impactlab.cli import main

def peak_kb():  # VmHWM: unlike ru_maxrss, not inherited over exec from pytest's worker
    return next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:"))


base = peak_kb() / 1024
start = time.perf_counter()
code = main(["analyze", sys.argv[1], "-o", sys.argv[2]])
seconds = time.perf_counter() - start
peak = peak_kb() / 1024
run = load_log(sys.argv[1])
frames = [*run.bodies.values(), run.energy, run.contacts]
decoded = sum(f.estimated_size() for f in frames) / 2**20
print(json.dumps({"code": code, "base_mib": base, "peak_mib": peak, "decoded_mib": decoded,
                  "steps": run.energy.height, "seconds": seconds}))
"""


def measure(log: Path, out: Path) -> dict:
    """Peak RSS of `impactlab analyze LOG` over the imports, and the decoded frames' size."""
    done = subprocess.run(
        [sys.executable, "-c", MEASURE, str(log), str(out)],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_peak_memory_of_analyzing_a_long_log(tmp_path):
    spec = tmp_path / "long.toml"
    spec.write_text(
        toml(drop("long", timestep=0.0001, max_time=10.0))
    )  # 100,001 logged steps, contact half the time
    (result,) = record_runs(plan([spec]), tmp_path / "logs")
    m = measure(result.path, tmp_path / "results")
    assert m["code"] == 0 and m["steps"] == 100_001
    growth = m["peak_mib"] - m["base_mib"]
    print(f"peak RSS +{growth:.0f} MiB for {m['decoded_mib']:.1f} MiB of decoded frames")
    assert growth < 10 * m["decoded_mib"] + 100
