"""The report's "handout as written" table and the Step 1 loose ends, from the tables."""

from __future__ import annotations

import polars as pl
import pytest

from impactlab.analyze.report.blocks import Table
from impactlab.analyze.report.context import Tables
from impactlab.analyze.report.findings import at_rest as _at_rest
from impactlab.analyze.report.handout import as_written

RUNS = pl.DataFrame(
    {
        "run_id": ["d1", "d2", "r1", "w1", "c1"],
        "experiment": ["drop", "drop", "drop_restitution", "collision_as_written", "collision"],
        "e_velocity_first": [None, 0.044, 0.8, None, None],
    }
)
COLLISIONS = pl.DataFrame(
    {
        "run_id": ["w1", "c1"],
        "complete": [False, True],
        "e_velocity": [None, 0.136],
        "note": ["the collision never happened", ""],
        "v1n_after_mps": [2.0, 0.2],
        "v2n_after_mps": [-1.0, 0.7],
        "v1n_after_elastic_mps": [-1.0, -1.0],
        "momentum_rel_change": [None, 1e-15],
        "touched_by": [None, ""],
        "gravity_impulse_rel": [None, 0.0],
    }
)


def tables(runs: pl.DataFrame, collisions: pl.DataFrame) -> Tables:
    return Tables(runs, pl.DataFrame(), collisions, pl.DataFrame(), {}, {})


def test_each_step_as_written_beside_its_correction_with_numbers_and_why():
    heading, _, table = as_written(tables(RUNS, COLLISIONS))
    assert isinstance(table, Table) and heading.text == "The handout as written"
    drops, step3 = table.frame.iter_rows(named=True)
    assert drops["written"] == "drop: e = 0.0440 at the first impact (1 of 2 runs rebound)"
    assert (
        drops["corrected"]
        == "drop_restitution: e = 0.800 at the first impact (1 of 1 runs rebound)"
    )
    assert "0.1 m/s velocity threshold" in table.notes[0]
    assert "no collision: the collision never happened; v1' = 2.00 m/s" in step3["written"]
    kept = (
        "e = 0.136; momentum is conserved in 1 collision (relative change at most 1.0 \u00d7 10⁻¹⁵"
    )
    assert kept in step3["corrected"]
    assert "meet at 0.6 s" in table.notes[1]
    assert table.frame.height == 2  # neither sweep was analyzed: no row, no invented numbers


def test_no_handout_experiments_no_section():
    runs = RUNS.with_columns(pl.lit("mine").alias("experiment"))
    assert as_written(tables(runs, COLLISIONS)) == []


def test_a_collision_that_changes_momentum_is_not_said_to_keep_it():
    runs = pl.DataFrame(
        {"run_id": ["w1", "c1"], "experiment": ["collision_as_written", "collision"]}
    )
    col = COLLISIONS.with_columns(pl.Series("momentum_rel_change", [None, 0.3]))
    (_, _, table) = as_written(tables(runs, col))
    changed = "momentum is conserved in 0 of 1 collisions (relative change up to 0.30)"
    assert changed in table.frame["corrected"][0]


def test_runs_at_rest_say_why_they_end_early_and_below_zero():
    ground = pl.DataFrame(
        {
            "run_id": ["free_fall-1", "drop-2"],
            "experiment": ["free_fall", "drop"],
            "reason": ["bodies at rest", "time limit 2 s"],
            "duration_s": [1.1505, 2.0],
            "energy_final_J": [-0.00357, 0.1],
        }
    )
    (line,) = _at_rest(ground)
    assert line.startswith("1 run(s) stop once every body is at rest, free_fall-1 at 1.15 s.")
    assert "(-0.00357 J)" in line and "soft contact" in line
    assert _at_rest(ground.filter(pl.col("reason") != "bodies at rest")) == []


@pytest.mark.slow
def test_figure_titles_say_what_the_contact_is_and_the_sweep_point_in_words():
    from impactlab.analyze.report.run_figures import contact_words
    from impactlab.logs.labels import run_label
    from impactlab.logs.metadata import GeomContact, PairTarget

    raw = GeomContact((0.02, 1.0), (0.9, 0.95, 0.001))
    one = [PairTarget("plane", "a", 0.8, (1.0, 2.0)), PairTarget("plane", "b", 0.8, None)]
    assert contact_words(one, raw) == "restitution = 0.8"
    assert contact_words([], raw) == "solref 0.02 1; solimp 0.9 0.95 0.001"
    pairs = [PairTarget("a", "plane", 0.42, None), PairTarget("b", "plane", 0.0, None)]
    assert contact_words(pairs, None) == "restitution a/plane = 0.42, b/plane = 0"
    assert contact_words([], None) == ""
    assert (
        run_label("drop", {"bodies.ball.pos": [0.0, 0.0, 3.0]}) == "drop: ball released at z = 3 m"
    )
    assert run_label("e", {"contact.restitution": 0.9}) == "e: restitution = 0.9"
    assert run_label("drop", {}) == "drop"


@pytest.mark.slow
def test_restitution_figure_draws_each_experiments_target(monkeypatch, tmp_path):
    from impactlab.analyze.report import figures

    seen = []
    monkeypatch.setattr(figures, "save_figure", lambda fig, path: seen.append(fig) or path)
    bounces = pl.DataFrame(
        {
            "run_id": ["a", "a", "b"],
            "complete": [True, True, True],
            "v_in_mps": [-4.0, -3.2, -2.0],
            "e_velocity": [0.80, 0.799, 0.05],
            "e_apex": [0.801, None, None],
        }
    )
    figures.restitution_figure(
        bounces,
        pl.DataFrame(),
        {"a": "drop_restitution", "b": "drop"},
        path=tmp_path / "r.png",
        targets={"drop_restitution": [0.8]},
    )
    (ax,) = seen[0].axes
    dashed = [line for line in ax.get_lines() if line.get_linestyle() == "--"]
    assert [tuple(line.get_ydata()) for line in dashed] == [(0.8, 0.8)]
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "drop_restitution: target" in legend and "drop" in legend
    assert "(m/s)" in ax.get_xlabel()


@pytest.mark.slow
def test_restitution_figure_of_collisions_without_a_bounce(monkeypatch, tmp_path):
    """Two balls and no ground (experiments/collision.toml): the bounces frame the analysis
    passes has no columns but `complete`; the body-body collision alone is drawn."""
    from impactlab.analyze.report import figures

    seen = []
    monkeypatch.setattr(figures, "save_figure", lambda fig, path: seen.append(fig) or path)
    collisions = pl.DataFrame(
        {
            "run_id": ["a"],
            "complete": [True],
            "v1n_before_mps": [2.0],
            "v2n_before_mps": [-1.0],
            "e_velocity": [0.8],
        }
    )
    figures.restitution_figure(pl.DataFrame(), collisions, {"a": "a"}, path=tmp_path / "r.png")
    (ax,) = seen[0].axes
    line = ax.get_lines()[0]  # then the marker families' legend entries, empty
    assert (tuple(line.get_xdata()), tuple(line.get_ydata())) == ((3.0,), (0.8,))


def test_a_bounce_decay_figure_needs_two_complete_bounces():
    from impactlab.analyze.write import _has_decay

    bounces = pl.DataFrame(
        {"run_id": ["one", "two", "two"], "body": ["ball"] * 3, "complete": [True, True, True]}
    )
    assert not _has_decay(bounces, ["one"])  # one bounce: one height, no decay to show
    assert _has_decay(bounces, ["one", "two"])
    assert not _has_decay(bounces.clear(), ["two"])
