"""The sweep parameter columns beside the runs table: a table that has them already (an
analysis' runs table, as the report and summary read it) gets them anew, not twice."""

from __future__ import annotations

import json

import polars as pl
from polars.testing import assert_frame_equal

from impactlab.analyze.tables.studies import parameters, studies, study_parameters


def test_parameters_are_set_once_and_the_studies_are_the_swept_experiments():
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
    _, once = parameters(runs)
    assert once.columns == ["run_id", "experiment", "sweep", "note", "ball.mass", "ball.pos[2]"]
    assert_frame_equal(parameters(once)[1], once)  # computed again: the same table
    assert study_parameters(once, "drop") == ["ball.pos[2]"]
    params, joined = parameters(runs)
    assert params == ["ball.mass", "ball.pos[2]"] and joined.equals(once)
    found = studies(joined.with_columns(partial=pl.lit(False)), params)
    assert list(found) == ["drop"]
    assert found["drop"].columns == ["run_id", "ball.pos[2]", "partial", "note"]
