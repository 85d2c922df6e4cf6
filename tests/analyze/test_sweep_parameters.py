"""The sweep parameter columns are joined to a runs table once: a table that has them
already (an analysis' runs table, as the report and summary read it) keeps them as they are."""

from __future__ import annotations

import json

import polars as pl
from polars.testing import assert_frame_equal

from impactlab.analyze.tables.studies import study_parameters, with_parameters


def test_parameters_are_joined_once():
    runs = pl.DataFrame(
        {
            "run_id": ["d-1", "d-2", "c-1"],
            "experiment": ["drop", "drop", "collide"],
            "sweep": [
                json.dumps({"ball.pos": [0, 0, 1.0]}),
                json.dumps({"ball.pos": [0, 0, 2.0]}),
                json.dumps({"ball.mass": 0.5}),
            ],
            "note": ["", "", ""],
        }
    )
    once = with_parameters(runs)
    assert once.columns == ["run_id", "experiment", "sweep", "note", "ball.mass", "ball.pos[2]"]
    assert with_parameters(once) is once  # the table made is its own answer, not a copy
    twice = with_parameters(once.clone())  # computed again: the same table
    assert_frame_equal(twice, once)
    assert study_parameters(once, "drop") == ["ball.pos[2]"]
