"""Temporary files a killed job left are removed when the folder is recorded into again."""

from __future__ import annotations

import subprocess
import sys

from specs import drop, write

from impactlab.record import plan, record_runs
from impactlab.record.folder import log_path


def test_stale_temporary_files_of_the_runs_are_removed_and_others_kept(tmp_path):
    out = tmp_path / "logs"
    out.mkdir()
    runs = plan([write(tmp_path, drop(max_time=0.02))])
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    name = log_path(out, runs[0]).name
    stale = out / f"{name}.{dead}.partial"
    other = out / f"another-run.mcap.{dead}.partial"  # not a run of this job: left alone
    stale.write_bytes(b"half")
    other.write_bytes(b"half")
    [result] = record_runs(runs, out, threads=1)
    assert result.status == "recorded"
    assert not stale.exists() and other.exists()
