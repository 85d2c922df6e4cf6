"""The analysis' fast paths (taken on frames as the recorder writes them) give what their
general path gives on the same data in any order: MuJoCo's energy at given times, and a table written as one
part."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest
from polars.testing import assert_frame_equal

from impactlab.analyze.measure.energy import _mujoco_at
from impactlab.analyze.tables.combine import _join, _relaxed
from impactlab.files import write_parquet
from impactlab.logs.load import load_log

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "logs"


@pytest.fixture(scope="module")
def runs():
    logs = sorted(GOLDEN.glob("*.mcap"))
    assert len(logs) >= 4
    return [load_log(p) for p in logs]


def test_mujoco_energy_at_the_logged_times_equals_the_searched_one(runs):
    """At exactly the logged times (no search) and at the same times with one that was not
    logged (searched), the values agree where both have them."""
    energy = runs[0].energy
    t = energy["t_ns"].to_numpy()
    fast, found = _mujoco_at(energy, t, 0.5)
    assert found.all()
    asked = np.concatenate([t, [t[-1] + 1]])  # one time not logged: the general path
    searched, where = _mujoco_at(energy, asked, 0.5)
    np.testing.assert_array_equal(searched[:-1], fast)
    assert where[:-1].all() and not where[-1] and np.isnan(searched[-1])
    np.testing.assert_array_equal(fast, energy["total"].to_numpy() - 0.5)
    null_at_3 = pl.when(pl.col("t_ns") == t[3]).then(None).otherwise(pl.col("total"))
    nulls = energy.with_columns(null_at_3.alias("total"))
    values, found = _mujoco_at(nulls, t, 0.5)
    assert not found[3] and np.isnan(values[3]) and found.sum() == t.size - 1


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
