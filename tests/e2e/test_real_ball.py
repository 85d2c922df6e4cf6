"""The lab's real-ball experiment (experiments/real_ball.toml, issue 39), recorded and analyzed
as shipped: every bounce lands within 0.01 of the target e(v) at its speed, e falls with the
impact speed as the target does, the ITF drop from 2.54 m passes by its measured e, and Step 2
says so beside the constant contact's flat line."""

from __future__ import annotations

import polars as pl
import pytest
from paths import EXPERIMENTS

import impactlab
from impactlab.analyze.report.findings import E_TARGET_TOLERANCE
from impactlab.contact import RestitutionCurve
from impactlab.record.sweep import load_runs

pytestmark = pytest.mark.slow  # the designer fits the curve (10-14 s), then 7 drops: 50 s


def test_the_real_ball_follows_its_falling_target_and_passes_the_itf_test(tmp_path):
    spec = EXPERIMENTS / "real_ball.toml"
    (first, *_) = load_runs(spec)
    curve = first.contact.restitution
    assert isinstance(curve, RestitutionCurve) and curve.span_mps == (0.5, 10.0)
    specs = [spec, EXPERIMENTS / "drop_restitution.toml"]
    paths = impactlab.record(specs, out=tmp_path / "logs").paths
    result = impactlab.analyze(paths, out=tmp_path / "results", figures=True, report=True)
    ball = result.bounces.filter(pl.col("run_id").str.starts_with("real_ball"))
    done = ball.filter(pl.col("complete"))
    assert done.height == 12 and done["target_e"].null_count() == 0
    off = (done["e_velocity"] - done["target_e"]).abs().max()
    assert off <= E_TARGET_TOLERANCE  # the designer's promise for a curve
    speeds = -done["v_in_mps"]
    assert speeds.min() < 1.0 and speeds.max() > 8.9  # 0.7 .. 9 m/s
    by_speed = done.sort("v_in_mps", descending=True)["e_velocity"]  # slowest first
    assert by_speed[0] - by_speed[-1] > 0.1  # e falls with the impact speed

    report = (tmp_path / "results" / "report.md").read_text()
    assert "real_ball: the contact's target e falls by" in report
    assert "is the ITF tennis ball drop test (2.54 m, impact at 7.06 m/s)" in report
    assert "so it passes" in report
    assert "does not depend on it" in report  # drop_restitution's flat line
    assert (tmp_path / "results" / "figures" / "restitution-vs-speed.png").stat().st_size
