"""The analysis' fast paths (taken on frames as the recorder writes them) give what their
general path gives on the same data in any order: state lookups, MuJoCo's energy at given
times, in-contact flags, the split of rows by run, and a table written as one part."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest
from polars.testing import assert_frame_equal

from impactlab.analyze.measure.analysis import is_in_sorted
from impactlab.analyze.measure.contact_intervals import _run_blocks
from impactlab.analyze.measure.energy import _mujoco_at
from impactlab.analyze.measure.state_table import StateTable
from impactlab.analyze.measure.states import states_long
from impactlab.analyze.tables.combine import _join, _relaxed
from impactlab.files import write_parquet
from impactlab.logs.load import load_log

GOLDEN = Path(__file__).resolve().parents[1] / "golden" / "logs"


@pytest.fixture(scope="module")
def runs():
    logs = sorted(GOLDEN.glob("*.mcap"))
    assert len(logs) >= 4
    return [load_log(p) for p in logs]


def test_state_lookups_do_not_depend_on_the_row_order(runs):
    """StateTable over states_long (keys already sorted: no sort) and over the same rows
    shuffled (the general path: ranked and sorted) finds the same states, NaN where none."""
    states, _ = states_long(runs)
    shuffled = states[np.random.default_rng(1).permutation(states.height)]
    blocks = states.select("run_id", "body").unique(maintain_order=True).rows()
    asked = [(r, b, row) for r, b in blocks for row in (-1, 0, 1, 7, 10**6)]
    asked += [(blocks[0][0], "no such body", 0), (blocks[0][0], None, 0)]
    ids, bodies, rows = (list(x) for x in zip(*asked, strict=True))
    fast = StateTable(states)
    general = StateTable(shuffled)
    assert fast.order is None and general.order is not None
    a = fast.at(ids, bodies, np.array(rows, dtype=float))
    b = general.at(ids, bodies, np.array(rows, dtype=float))
    for name in ("t", "x", "q", "v", "w"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert np.isfinite(a.t).sum() == 3 * len(blocks)  # rows 0, 1 and 7 of every body
    first = states.filter(pl.col("row") == 7).row(0, named=True)
    i = asked.index((first["run_id"], first["body"], 7))
    assert a.x[i].tolist() == [first["x"], first["y"], first["z"]]


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


def test_in_contact_flags_equal_numpy_isin():
    rng = np.random.default_rng(7)
    for size in (0, 1, 50):
        values = rng.integers(0, 100, 300)
        inside = np.sort(rng.choice(100, size=size, replace=False))
        np.testing.assert_array_equal(is_in_sorted(values, inside), np.isin(values, inside))


def test_rows_split_by_run_in_blocks_or_interleaved():
    rows = pl.DataFrame({"run_id": ["a", "a", "b", "b", "b"], "t_ns": [1, 2, 1, 2, 3]})
    split = _run_blocks(rows, rows["t_ns"].to_numpy())
    assert [(r, v.tolist()) for r, v in split] == [("a", [1, 2]), ("b", [1, 2, 3])]
    mixed = rows[[0, 2, 1, 3, 4]]
    split = _run_blocks(mixed, mixed["t_ns"].to_numpy())
    assert [(r, v.tolist()) for r, v in split] == [("a", [1, 2]), ("b", [1, 2, 3])]


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
