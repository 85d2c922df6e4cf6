"""Figures are drawn again only when what they show changed (`impactlab.analyze.report.figure_cache`):
a second analysis of the same logs into the same folder copies every figure, a changed
input, a changed figure code or a foreign PNG of the same name is drawn."""

from __future__ import annotations

import shutil
from pathlib import Path

import paths
import pytest

from impactlab.analyze.job import run_analysis
from impactlab.analyze.report import figure_cache
from impactlab.analyze.report import figures as drawing

pytestmark = pytest.mark.slow  # figures drawn in worker processes

GOLDEN = paths.GOLDEN / "logs"
DRAWERS = (
    "energy_figure",
    "collision_figure",
    "bounce_decay_figure",
    "restitution_figure",
    "collision_study_figure",
    "bounce_study_figure",
)


@pytest.fixture
def drawn(monkeypatch) -> list[str]:
    """The names of the figures drawn (not copied), in order."""
    names: list[str] = []
    for name in DRAWERS:
        draw = getattr(drawing, name)

        def counted(*args, _draw=draw, **kwargs):
            names.append(kwargs["path"].name)
            return _draw(*args, **kwargs)

        monkeypatch.setattr(drawing, name, counted)
    return names


def pngs(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((out / "figures").glob("*.png"))}


def analyzed_drop(tmp_path: Path) -> tuple[Path, Path]:
    """A folder holding the golden drop's log, and its analysis into `out`."""
    logs = tmp_path / "logs"
    logs.mkdir()
    shutil.copy(GOLDEN / "drop_bounces.mcap", logs)
    out = tmp_path / "out"
    assert run_analysis([logs], out).exit_code == 0
    return logs, out


def test_unchanged_figures_are_copied_changed_ones_drawn(tmp_path, drawn, monkeypatch):
    logs, out = analyzed_drop(tmp_path)
    first = pngs(out)
    assert "restitution-vs-speed.png" in first and any(n.startswith("energy-") for n in first)
    assert sorted(drawn) == sorted(first)  # a new folder: everything drawn
    report = (out / "report.md").read_text()

    drawn.clear()
    assert run_analysis([logs], out).exit_code == 0
    assert drawn == []  # nothing changed: nothing drawn again
    assert pngs(out) == first
    assert (out / "report.md").read_text() == report

    # another run joins: the figures over all runs change, the first run's own do not
    shutil.copy(GOLDEN / "drop_restitution.mcap", logs)
    assert run_analysis([logs], out).exit_code == 0
    assert "restitution-vs-speed.png" in drawn
    assert not any(n in first and n.startswith("energy-") for n in drawn)

    # a PNG of the same name that is not this figure (a user's, another version's) is drawn
    energy = next(n for n in first if n.startswith("energy-"))
    shutil.copy(out / "figures" / "restitution-vs-speed.png", out / "figures" / energy)
    drawn.clear()
    assert run_analysis([logs], out).exit_code == 0
    assert drawn == [energy]
    assert pngs(out)[energy] == first[energy]

    # new figure code: every figure is drawn again
    monkeypatch.setattr(figure_cache, "code_version", lambda: "other code")
    drawn.clear()
    assert run_analysis([logs], out).exit_code == 0
    assert sorted(drawn) == sorted(pngs(out))


def test_key_follows_the_data():
    import polars as pl

    frame = pl.DataFrame({"t": [0.0, 1.0], "e": [1.0, 0.5]})
    key = figure_cache.figure_key("energy", frame, "title")
    assert key == figure_cache.figure_key("energy", frame.clone(), "title")
    assert key != figure_cache.figure_key("energy", frame.with_columns(pl.col("e") * 2), "title")
    assert key != figure_cache.figure_key("energy", frame, "another title")
    assert key != figure_cache.figure_key("decay", frame, "title")
    assert key != figure_cache.figure_key("energy", frame.head(1), "title")


def test_summary_figures_drawn_by_workers_equal_those_drawn_here(tmp_path):
    """With worker processes up, the summary figures are drawn there: the same figures (and
    keys) as drawn in this process."""
    from impactlab.executors.processes import ProcessExecutor

    logs = sorted(GOLDEN.glob("*.mcap"))
    here, there = tmp_path / "here", tmp_path / "there"
    assert run_analysis(logs, here).exit_code == 0
    executor = ProcessExecutor(workers=2, min_items=1)
    try:
        assert run_analysis(logs, there, executor=executor).exit_code == 0
        assert executor._pool  # the workers were up for the summary figures
    finally:
        executor.close()
    a, b = pngs(here), pngs(there)
    assert a.keys() == b.keys() and {"restitution-vs-speed.png"} <= a.keys()
    for name in a:
        assert figure_cache.png_key(a[name]) == figure_cache.png_key(b[name]), name
    assert (here / "report.md").read_text().replace(str(here), "") == (
        there / "report.md"
    ).read_text().replace(str(there), "")


def test_a_figure_failing_in_a_worker_fails_here_with_its_error(tmp_path):
    from impactlab.executors.base import TaskOutcome

    class Failing:
        name = "fake"
        slots = 2

        def map(self, fn, items):
            for i, _ in enumerate(items):
                yield TaskOutcome(i, error="worker said no")

    def broken() -> Path:
        raise ValueError("cannot draw this")

    jobs = [(tmp_path / f"{i}.png", "key", broken) for i in range(2)]
    with pytest.raises(ValueError, match="cannot draw this"):
        figure_cache.draw_all(jobs, Failing())


@pytest.mark.parametrize("keep", [0.5, 0.99])
def test_a_damaged_figure_is_drawn_again(tmp_path, drawn, keep):
    """A PNG of the last analysis cut short (a full disk, a copy interrupted) is never
    published again: its key is not trusted, the figure is drawn anew and whole."""
    logs, out = analyzed_drop(tmp_path)
    first = pngs(out)
    energy = next(n for n in first if n.startswith("energy-"))
    whole = first[energy]
    (out / "figures" / energy).write_bytes(whole[: int(len(whole) * keep)])
    drawn.clear()
    assert run_analysis([logs], out).exit_code == 0
    assert drawn == [energy]
    assert pngs(out)[energy].endswith(figure_cache.PNG_END)
    assert figure_cache.png_key(pngs(out)[energy]) == figure_cache.png_key(whole)
