"""The analysis streams its tables to Parquet as the batches finish: the same tables and
summary.json as one big batch, and a driver whose memory does not grow with the runs."""

from __future__ import annotations

import gc
import json
import math
import tracemalloc
from pathlib import Path

import polars as pl
import pytest
from polars.testing import assert_frame_equal
from specs import SOFT, drop, toml

from impactlab.analyze import batch as batch_module
from impactlab.analyze import write as write_module
from impactlab.analyze.job import run_analysis
from impactlab.analyze.tables import combine as combine_module
from impactlab.record import plan, record_runs

TABLES = ("runs", "bounces", "collisions", "energy", "phases")


def sweep(folder: Path, runs: int, max_time: float) -> list[Path]:
    """`runs` drops of a ball from 0.15 m up (they bounce within `max_time`), recorded."""
    points = [[0.0, 0.0, round(0.15 + 0.0005 * i, 4)] for i in range(runs)]
    spec = folder / f"stream_{runs}.toml"
    spec.write_text(
        toml(
            drop(
                "stream_drop",
                z=0.2,
                timestep=0.0005,
                contact=SOFT,
                max_time=max_time,
                sweep={"ball.pos": points},
            )
        )
    )
    return sorted(record_runs(plan([spec]), folder / f"logs_{runs}").paths)


@pytest.fixture(scope="module")
def logs200(tmp_path_factory) -> list[Path]:
    return sweep(tmp_path_factory.mktemp("stream"), 200, 0.4)


def batch_size(monkeypatch: pytest.MonkeyPatch, logs: int) -> None:
    """Analyze `logs` logs together, write the tables every `logs` runs and summary.json's
    runs from slices of `logs` rows."""
    monkeypatch.setattr(batch_module, "BATCH_LOGS", logs)
    monkeypatch.setattr(combine_module, "REDUCE_EVERY", logs)
    monkeypatch.setattr(write_module, "SUMMARY_SLICE", logs)


def close(a: object, b: object, where: str = "") -> None:
    """Two JSON documents equal, floats within a relative 1e-9."""
    if isinstance(a, float) or isinstance(b, float):
        assert isinstance(a, int | float) and isinstance(b, int | float), where
        assert math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12), where
    elif isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), where
        for key in a:
            close(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            close(x, y, f"{where}[{i}]")
    else:
        assert a == b, where


@pytest.mark.slow
def test_streamed_tables_equal_one_batch(logs200, tmp_path, monkeypatch):
    """200 logs in batches of 7 (29 parts per table) against one batch of all 200, and
    against the tables held in memory (no folder)."""
    batch_size(monkeypatch, 7)
    small = run_analysis(logs200, tmp_path / "small", figures=False)
    batch_size(monkeypatch, 10_000)
    big = run_analysis(logs200, tmp_path / "big", figures=False)
    held = run_analysis(logs200, None)
    assert small.exit_code == big.exit_code == held.exit_code == 0
    assert big.runs.height == 200 and big.runs["n_bounces"].sum() >= 200  # drops that bounce
    for name in TABLES:
        a = pl.read_parquet(tmp_path / "small" / f"{name}.parquet")
        b = pl.read_parquet(tmp_path / "big" / f"{name}.parquet")
        assert a.height == b.height, name
        assert_frame_equal(a, b, check_exact=False, rel_tol=1e-9, abs_tol=1e-12)
        assert_frame_equal(
            a,
            held.table(name) if name != "runs" else held.runs,
            check_exact=False,
            rel_tol=1e-9,
            abs_tol=1e-12,
        )
        # the result reads the published file
        got = small.runs if name == "runs" else small.table(name)
        assert_frame_equal(got, a)
    assert not list((tmp_path / "small").glob("*/part-*.parquet"))  # parts joined, removed
    summaries = [json.loads((tmp_path / d / "summary.json").read_text()) for d in ("small", "big")]
    assert len(summaries[0]["runs"]) == 200
    close(summaries[0], summaries[1])
    assert small.energy_logged == big.energy_logged
    assert small.scan("energy").select(pl.len()).collect().item() == big.energy.height


def driver_peak(logs: list[Path], out: Path) -> int:
    """The peak of the driver's Python allocations (tracemalloc) analyzing `logs` into `out`,
    tables only, in batches of 32."""
    gc.collect()
    tracemalloc.start()
    try:
        result = run_analysis(logs, out, figures=False, report=False)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert result.exit_code == 0 and result.runs.height == len(logs)
    return peak


@pytest.mark.slow
def test_driver_memory_does_not_grow_with_the_runs(tmp_path, monkeypatch):
    """400 logs need no more of the driver's Python memory than 100 (within 1.3x): it holds
    one batch of frames and a small brief per run, not every run's tables and metadata."""
    logs = sweep(tmp_path, 400, 0.05)
    batch_size(monkeypatch, 32)
    run_analysis(logs[:32], tmp_path / "warm", figures=False, report=False)  # imports, caches
    small = driver_peak(logs[:100], tmp_path / "out100")
    large = driver_peak(logs, tmp_path / "out400")
    assert large <= 1.3 * small, (
        f"driver peak {large / 1e6:.1f} MB for 400 logs, {small / 1e6:.1f} MB for 100"
    )
