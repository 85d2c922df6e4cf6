"""Readable run labels, one rule for the report's tables, its figures and the replay: the sweep
point in words (of a swept vector, the components that vary), the run id's end where two runs
would read the same, one label per run id however often the run appears."""

from __future__ import annotations

import json

import polars as pl

from impactlab.analyze.report.context import with_labels
from impactlab.logs import labels as rule
from impactlab.logs.labels import run_labels


def _runs(*rows: tuple[str, str, dict]) -> pl.DataFrame:
    return pl.DataFrame(
        {
            "run_id": [r[0] for r in rows],
            "experiment": [r[1] for r in rows],
            "sweep": [json.dumps(r[2]) for r in rows],
        }
    )


def test_labels_words_ends_and_repeats():
    runs = _runs(
        ("drop-a-1111", "drop", {"ball.pos": [0, 0, 1.0000001]}),  # reads "1 m" ...
        ("drop-b-2222", "drop", {"ball.pos": [0, 0, 1.0000002]}),  # ... as this one does
        ("drop-c-3333", "drop", {"ball.pos": [0, 0, 2.0]}),
        ("drop-c-3333", "drop", {"ball.pos": [0, 0, 2.0]}),  # the same log given twice
        ("free-x", "free", {}),
    )
    labels = dict(run_labels(runs).iter_rows())
    assert labels == {
        "drop-a-1111": "drop: ball released at z = 1 m (1111)",
        "drop-b-2222": "drop: ball released at z = 1 m (2222)",
        "drop-c-3333": "drop: ball released at z = 2 m",
        "free-x": "free",
    }
    frame = pl.DataFrame({"run_id": ["free-x", "drop-c-3333", "unknown"], "v": [1, 2, 3]})
    labeled = with_labels(frame, run_labels(runs))
    assert labeled.columns == ["run", "run_id", "v"]
    assert labeled["run"].to_list() == ["free", "drop: ball released at z = 2 m", "unknown"]


def test_a_run_without_its_parameter_reads_as_its_experiment():
    runs = _runs(
        ("mix-a-1", "mix", {"ball.mass": 0.5}),
        ("mix-b-2", "mix", {"ball.mass": 2.0}),
        ("mix-c-3", "mix", {}),
    )
    labels = dict(run_labels(runs).iter_rows())
    assert labels == {
        "mix-a-1": "mix: ball mass = 0.5 kg",
        "mix-b-2": "mix: ball mass = 2 kg",
        "mix-c-3": "mix",
    }
    assert run_labels(runs.clear()).columns == ["run_id", "run"]


def test_a_swept_vector_shows_the_components_that_vary_and_a_lone_run_those_not_zero():
    runs = _runs(
        ("s-1", "sweep", {"contact.solimp": [0.5, 0.95, 0.001]}),
        ("s-2", "sweep", {"contact.solimp": [0.9, 0.95, 0.001]}),
        ("one-3", "one", {"bodies.ball.pos": [0.5, 0.0, 3.0], "ball.mass": 2.0}),
    )
    assert dict(run_labels(runs).iter_rows()) == {
        "s-1": "sweep: solimp[0] = 0.5",
        "s-2": "sweep: solimp[0] = 0.9",
        "one-3": "one: ball released at x = 0.5 m, ball released at z = 3 m, ball mass = 2 kg",
    }
    lone = rule.run_label("one", {"bodies.ball.pos": [0.5, 0.0, 3.0], "ball.mass": 2.0})
    assert lone == dict(run_labels(runs.tail(1)).iter_rows())["one-3"]  # a figure's title
    assert rule.run_label("free", {}) == "free"
