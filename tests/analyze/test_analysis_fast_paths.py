"""MuJoCo's energy compared at the times it was logged; the table parts' fast join (a table
written as one part, parts of different types) gives what one concatenation gives."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from polars.testing import assert_frame_equal

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.analyze.tables.combine import _join, _relaxed
from impactlab.files import write_parquet
from impactlab.logs.load import load_log

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "logs"


@pytest.fixture(scope="module")
def runs():
    logs = sorted(GOLDEN.glob("*.mcap"))
    assert len(logs) >= 4
    return [load_log(p) for p in logs]


def test_mujoco_energy_is_compared_at_the_times_it_was_logged(runs):
    """The energy table's MuJoCo total is the logged one, shifted by one constant per run;
    a time whose MuJoCo total is missing (null) has none, and no difference."""
    run = runs[0]
    t3 = run.energy["t_ns"][3]
    for damaged in (False, True):
        energy = run.energy
        if damaged:
            null_at_3 = pl.when(pl.col("t_ns") == t3).then(None).otherwise(pl.col("total"))
            energy = energy.with_columns(null_at_3.alias("total"))
        total = analyze_run(replace(run, energy=energy)).energy.filter(pl.col("is_total"))
        joined = total.join(energy, on="t_ns")
        assert joined.height == energy.height == total.height
        known = joined.filter(pl.col("total").is_not_null())
        shift = (known["total"] - known["mujoco_total_J"]).to_numpy()
        np.testing.assert_allclose(shift, shift[0], rtol=0, atol=1e-12)
        diff = known["mujoco_total_J"] - known["total_J"]
        np.testing.assert_allclose(known["mujoco_diff_J"].to_numpy(), diff.to_numpy(), atol=1e-15)
        missing = joined.filter(pl.col("total").is_null())
        assert missing.height == damaged
        assert (
            missing["mujoco_total_J"].is_null().all() and missing["mujoco_diff_J"].is_null().all()
        )


def test_one_part_is_renamed_and_two_are_joined(tmp_path):
    """A table of one part is that part (renamed); of two, their diagonal concatenation."""
    a = pl.DataFrame({"run_id": ["x", "y"], "v": [1.0, 2.0]})
    b = pl.DataFrame({"run_id": ["z"], "v": [3.0], "note": ["late column"]})
    for folder in ("one", "two"):
        (tmp_path / folder).mkdir()
    one = write_parquet(a, tmp_path / "one" / "part-000000.parquet")
    out = _join([one], tmp_path / "one.parquet", a.schema)
    assert not one.exists() and not one.parent.exists()
    assert_frame_equal(pl.read_parquet(out), a)
    parts = [
        write_parquet(f, tmp_path / "two" / f"part-{i:06d}.parquet") for i, f in enumerate((a, b))
    ]
    out = _join(parts, tmp_path / "two.parquet", _relaxed(a.schema, b.schema))
    assert_frame_equal(pl.read_parquet(out), pl.concat([a, b], how="diagonal_relaxed"))
    assert not any(p.exists() for p in parts)


@pytest.mark.parametrize(
    "first, second",
    [
        ({"v": [1, 2]}, {"v": [1.5]}),  # integers widened to floats
        ({"v": pl.Series([1], dtype=pl.Int32)}, {"v": [3]}),  # to a wider integer
        ({"v": pl.Series([None, None], dtype=pl.Null)}, {"v": [1.5]}),  # an all-null column
        ({"v": [[1.0]]}, {"v": pl.Series([None], dtype=pl.Null)}),  # a list, then nulls
        ({"v": [1.5]}, {"v": ["text"]}),  # floats and text: the fallback's concatenation
        ({"v": [True]}, {"v": [3]}),  # booleans and integers: the fallback too
    ],
)
def test_parts_of_different_types_join_to_their_relaxed_concatenation(tmp_path, first, second):
    """Whatever the parts' types, the joined table is their diagonal, relaxed concatenation
    (the streaming scan widens what it can; the rest goes through one scan per part)."""
    frames = [pl.DataFrame({"run_id": ["a"] * len(c["v"]), **c}) for c in (first, second)]
    parts = [write_parquet(f, tmp_path / f"part-{i:06d}.parquet") for i, f in enumerate(frames)]
    out = _join(
        parts, tmp_path.parent / f"{tmp_path.name}.parquet", _relaxed(*(f.schema for f in frames))
    )
    assert_frame_equal(pl.read_parquet(out), pl.concat(frames, how="diagonal_relaxed"))
    assert not tmp_path.exists()
