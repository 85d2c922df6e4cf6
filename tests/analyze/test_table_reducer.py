"""The analysis folds each run's tables in as it arrives: the same tables as one concatenation
of every run's frames, with the energy table decimated as it is written."""

from __future__ import annotations

import dataclasses

import paths
import polars as pl
import pytest
from polars.testing import assert_frame_equal

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.analyze.tables import combine as tables_module
from impactlab.analyze.tables.combine import TableReducer
from impactlab.analyze.tables.decimate import ENERGY_ROWS_PER_RUN, decimate
from impactlab.logs.load import load_log

GOLDEN = paths.GOLDEN / "logs"


@pytest.fixture(scope="module")
def analyses():
    logs = sorted(GOLDEN.glob("*.mcap"))
    assert len(logs) >= 4
    return [analyze_run(load_log(p)) for p in logs]


@pytest.mark.parametrize("every", [1, 2, 3, 1000])
def test_folded_tables_equal_one_concatenation(analyses, monkeypatch, every):
    """Runs of different experiments (drops, collisions, a box), folded every `every` runs."""
    monkeypatch.setattr(tables_module, "REDUCE_EVERY", every)
    reducer = TableReducer()
    for a in analyses:
        stripped = reducer.take(a)
        assert stripped.bounces.is_empty() and stripped.energy.is_empty()
        assert stripped.run.run_id == a.run.run_id  # the metadata stays
    result = reducer.result(None, [])

    def concat(name: str) -> pl.DataFrame:
        frames = [getattr(a, name) for a in analyses if getattr(a, name).width]
        return pl.concat(frames, how="diagonal_relaxed")

    for name in ("bounces", "collisions", "phases"):
        assert_frame_equal(getattr(result, name), concat(name), check_exact=True)
    assert_frame_equal(result.energy, decimate(concat("energy")), check_exact=True)
    full = concat("energy")
    assert result.energy_logged == (
        full.height,
        int(full.group_by("run_id", "body").len()["len"].max()),
    )
    assert result.runs.height == len(analyses)


@pytest.mark.parametrize("every", [1, 2, 3])
def test_written_parts_join_to_one_concatenation(analyses, monkeypatch, tmp_path, every):
    """With a folder, the parts written every `every` runs (drops, collisions, a box; parts
    with different columns and types) are joined into the same tables, and removed."""
    monkeypatch.setattr(tables_module, "REDUCE_EVERY", every)
    first, second, *rest = analyses
    varied = [  # a column all null (type Null) in one run, a column only one run has
        dataclasses.replace(
            first,
            bounces=first.bounces.with_columns(e_velocity=None),
            summary={**first.summary, "note": None, "only_here": 2},  # in the runs table too
        ),
        dataclasses.replace(second, phases=second.phases.with_columns(extra=pl.lit(1.5))),
        *rest,
    ]
    reducer = TableReducer(folder=tmp_path)
    in_memory = TableReducer()
    for a in varied:
        reducer.take(a)
        in_memory.take(a)
    # the runs table's rows are written as they come, like the other tables
    assert len(list((tmp_path / "runs").glob("part-*.parquet"))) == len(varied) // every
    result = reducer.result(tmp_path, [])
    # the runs table's parts are read back: the table kept in memory without a folder
    assert_frame_equal(result.runs, in_memory.result(None, []).runs, check_exact=True)
    only = result.runs.select("run_id", "only_here").drop_nulls()
    assert only.rows() == [(first.run.run_id, 2)]

    def concat(name: str) -> pl.DataFrame:
        frames = [getattr(a, name) for a in varied if getattr(a, name).width]
        return pl.concat(frames, how="diagonal_relaxed")

    for name in ("bounces", "collisions", "phases"):
        assert result.sources[name] == tmp_path / f"{name}.parquet"
        assert_frame_equal(getattr(result, name), concat(name), check_exact=True)
    assert_frame_equal(result.energy, decimate(concat("energy")), check_exact=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        f"{n}.parquet" for n in ("bounces", "collisions", "energy", "phases")
    ]


def test_a_long_run_is_decimated_as_written(analyses):
    """A run with more than ENERGY_ROWS_PER_RUN rows per body keeps every k-th row and its
    last; its full count is kept for the report's note."""
    a = analyses[0]
    times = a.energy["t_s"].unique().sort()
    repeat = ENERGY_ROWS_PER_RUN // times.len() + 2
    long = pl.concat(
        [a.energy.with_columns(pl.col("t_s") + i * 1000.0) for i in range(repeat)]
    ).sort("body", "t_s", maintain_order=True)
    reducer = TableReducer()
    reducer.take(a.__class__(**{**a.__dict__, "energy": long}))
    result = reducer.result(None, [])
    assert_frame_equal(result.energy, decimate(long), check_exact=True)
    assert result.energy.height < long.height
    per_body = long.group_by("body").len()["len"].max()
    assert result.energy_logged == (long.height, per_body)
