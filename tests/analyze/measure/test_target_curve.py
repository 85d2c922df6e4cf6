"""A target e(v) from the spec to every impact (issue 39): the log's contact_targets carry the
curve's points (a constant target is written as before), and an impact's target_e is the curve
at its normal speed inside the pair's speed range, none outside, for bounces and collisions."""

from __future__ import annotations

import dataclasses
import importlib
import json

import numpy as np
import polars as pl
import pytest
from specs import drop

import impactlab
from impactlab.analyze.measure.analysis import _with_targets
from impactlab.analyze.measure.bounces import TARGET_SCHEMA, target_e
from impactlab.contact import RestitutionCurve, contact_params
from impactlab.logs import format as logformat
from impactlab.logs.load import load_log
from impactlab.physics import restitution_on_curve

contact_pairs = importlib.import_module("impactlab.record.contact_pairs")

XS, ES = (0.5, 1.0, 2.0, 4.0), (0.86, 0.85, 0.82, 0.78)


def _targets(rows: list[tuple]) -> pl.DataFrame:
    return pl.DataFrame(rows, schema=TARGET_SCHEMA, orient="row")


def test_target_e_is_the_curve_inside_the_range_and_none_outside():
    pairs = _targets(
        [
            ("r", "ball", "plane", 0.8, 0.5, 4.0, list(XS), list(ES)),
            ("r", "other", "plane", 0.7, 1.0, 3.0, None, None),
            ("r", "wide", "plane", 0.8, 0.4999, 4.0001, list(XS), list(ES)),  # a step wider
        ]
    )
    speeds = [0.4, 0.5, 0.75, 3.0, 4.0, 4.5]
    rows = pl.DataFrame(
        {
            "body": ["ball"] * 6 + ["other"] * 6 + ["wide", "wide", "nobody"],
            "speed": speeds * 2 + [0.49995, 4.00005, 1.0],
        }
    ).with_columns(run_id=pl.lit("r"), other=pl.lit("plane"))
    got = rows.join(pairs, on=["run_id", "body", "other"], how="left", maintain_order="left")
    found = got.select(target_e(pl.col("speed")).alias("t"))["t"].to_list()
    on_curve = restitution_on_curve(speeds, XS, ES)
    assert found[:6] == pytest.approx([None, *on_curve[1:5], None], abs=1e-15)
    assert found[6:12] == [None, None, None, 0.7, None, None]
    # a speed a step outside the curve, inside the widened range: held at the curve's end
    assert found[12:] == pytest.approx([0.86, 0.78, None], abs=1e-15)


def test_a_collision_gets_the_curve_at_its_closing_speed():
    pairs = _targets([("r", "a", "b", 0.8, 0.5, 4.0, list(XS), list(ES))])
    col = pl.DataFrame(
        {
            "run_id": ["r", "r"],
            "body1": ["a", "a"],
            "body2": ["b", "b"],
            "v1n_before_mps": [1.0, 5.0],
            "v2n_before_mps": [-0.5, 0.0],
            "target_e": [None, None],
        },
        schema_overrides={"target_e": pl.Float64},
    )
    got = _with_targets(col, pairs)["target_e"].to_list()
    assert got == pytest.approx([float(restitution_on_curve(1.5, XS, ES)), None])


def _stand_in(target, **options):
    """Not a designer: the constant one with the curve attached, so that the wiring from
    spec to log to analysis is tested while the contact package's designer is its own."""
    options.pop("reference_speed_mps", None)
    curve = target if isinstance(target, RestitutionCurve) else None
    params = contact_params(0.8 if curve else target, **options)
    return dataclasses.replace(params, curve=curve)


@pytest.mark.slow  # two recordings at dt 1e-5 s: 4 s
def test_the_curve_goes_through_the_log_to_every_bounce(tmp_path, monkeypatch):
    monkeypatch.setattr(contact_pairs, "_calibrated", _stand_in)
    contact = {"restitution": {"speed_mps": list(XS), "e": list(ES)}, "speed_range": [0.5, 4]}
    curved = drop("curved", z=0.6, timestep=1e-5, max_time=3.0, bounces=3, contact=contact)
    flat = drop("flat", z=0.6, timestep=1e-5, max_time=3.0, bounces=3, contact={"restitution": 0.8})
    paths = impactlab.record([curved, flat], out=tmp_path).paths
    logs = {load_log(p).experiment: load_log(p) for p in paths}

    (target,) = logs["curved"].contact_targets
    assert (target.curve_speed_mps, target.curve_e) == (XS, ES)
    assert not logs["curved"].checked.problems
    written = json.loads(logs["curved"].meta["contact_targets"])
    assert written[0]["curve_speed_mps"] == list(XS) and written[0]["curve_e"] == list(ES)
    # a constant target is written as it was before curves: no curve keys
    flat_written = json.loads(logs["flat"].meta["contact_targets"])
    assert set(flat_written[0]) == {"geom1", "geom2", "restitution", "speed_range_mps"}
    assert logs["flat"].contact_targets[0].curve_e is None
    assert "curve_speed_mps" in logformat.RUN_KEYS["contact_targets"]

    bounces = impactlab.analyze(paths).bounces.sort("run_id", "bounce")
    mine = bounces.filter(pl.col("run_id") == logs["curved"].run_id)
    assert mine.height == 3
    speeds = -mine["v_in_mps"].to_numpy()
    assert mine["target_e"].to_numpy() == pytest.approx(
        restitution_on_curve(speeds, XS, ES), abs=1e-12
    )
    assert np.ptp(mine["target_e"].to_numpy()) > 0.02  # the target follows the speed
    other = bounces.filter(pl.col("run_id") == logs["flat"].run_id)
    assert other["target_e"].to_list() == [0.8, 0.8, 0.8]
