"""What a person reads in a replay: panels for what a run has, one time axis, colours that
stand out on the plots, legends off the data, titles that fit.

From the layout a recording is sent with and the series colours read back from the recording
(Rerun's own reader); the golden logs are the runs: a drop on a plane, a head-on collision in
zero gravity, a point of a collision sweep, a box falling on its edge.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
import rerun.blueprint as rrb
from paths import GOLDEN

from impactlab.logs.geoms import body_rgba
from impactlab.logs.load import load_log
from impactlab.replay import blueprint as layout
from impactlab.replay import style
from impactlab.replay.convert import run_prefix
from impactlab.replay.recordings import log_runs

LOGS = {name: GOLDEN / "logs" / f"{name}.mcap" for name in ("drop_bounces", "collision")}
LOGS |= {"sweep_point": GOLDEN / "logs" / "collision_sweep_point.mcap"}
LOGS |= {"box_edge": GOLDEN / "logs" / "box_edge.mcap"}
RESULTS = GOLDEN / "results"
WCAG_GRAPHICS = 3.0  # the least contrast of graphics against their background (WCAG 2.1, 1.4.11)
CASES = {  # what a replay of these runs holds: one recording each, and all in one
    "drop": ["drop_bounces"],
    "collision": ["collision"],
    "box": ["box_edge"],
    "several": ["drop_bounces", "collision", "sweep_point"],
}


def _replay(names: list[str], folder: Path) -> tuple[rrb.Blueprint, dict[str, dict], dict]:
    """The layout sent with a recording of the runs (with the golden analysis), every static
    component of the recording by entity path, and every time series' samples (time in ns,
    value) by entity path, read back from the file."""
    from impactlab.replay.events import load_analysis

    runs = [load_log(LOGS[n]) for n in names]
    rec = rr.RecordingStream("impactlab", recording_id="layout", send_properties=False)
    memory = rec.memory_recording()
    try:
        blueprint = log_runs(rec, runs, load_analysis(RESULTS))
        data = memory.drain_as_bytes()
    finally:
        rec.disconnect()
    rrd = folder / "r.rrd"
    rrd.write_bytes(data)
    static: dict[str, dict] = {}
    parts: dict[str, list] = {}
    for chunk in rr.chunk.RrdReader(rrd).stream():
        batch = chunk.to_record_batch()
        if chunk.is_static:
            static.setdefault(chunk.entity_path, {}).update(batch.to_pylist()[-1])
        elif "Scalars:scalars" in batch.schema.names:
            t = batch.column("sim_time").cast("int64").to_numpy()
            v = np.array([x[0] for x in batch.column("Scalars:scalars").to_pylist()])
            parts.setdefault(chunk.entity_path, []).append((t, v))
    samples = {
        p: tuple(np.concatenate(x) for x in zip(*chunks, strict=True))
        for p, chunks in parts.items()
    }
    return blueprint, static, samples


@pytest.fixture(scope="module")
def replays(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple]:
    return {k: _replay(names, tmp_path_factory.mktemp(k)) for k, names in CASES.items()}


def _views(blueprint: rrb.Blueprint) -> list[rrb.View]:
    found, stack = [], [blueprint.root_container]
    while stack:
        item = stack.pop()
        if isinstance(item, rrb.View):
            found.append(item)
        else:
            stack += list(item.contents)
    return found[::-1]


def _plots(blueprint: rrb.Blueprint) -> dict[str, rrb.TimeSeriesView]:
    """The time series views by the family they show (P/series/<family>/**)."""
    out = {}
    for view in _views(blueprint):
        if isinstance(view, rrb.TimeSeriesView):
            (family,) = {c.split("/series/")[1].split("/")[0] for c in view.contents}
            out[family] = view
    return out


def _prop(view: rrb.View, archetype: str, field: str) -> list:
    value = getattr(view.properties[archetype], field)
    return [] if value is None else value.as_arrow_array().to_pylist()


def _rgb(packed: int) -> tuple[int, int, int]:
    return (packed >> 24 & 0xFF, packed >> 16 & 0xFF, packed >> 8 & 0xFF)


def _lines(static: dict[str, dict], family: str = "") -> dict[str, tuple[str, tuple]]:
    """Line series of the recording (under P/series/<family>): path -> (name, colour)."""
    return {
        path: (row["SeriesLines:names"][0], _rgb(row["SeriesLines:colors"][0]))
        for path, row in static.items()
        if f"/series/{family}" in path and "SeriesLines:colors" in row
    }


PANELS = {
    "drop": {"height", "velocity", "energy", "contact_force"},
    "collision": {"velocity", "energy", "momentum", "contact_force"},
    "box": {"height", "velocity", "energy", "contact_force"},
    "several": {"height", "velocity", "energy", "momentum", "contact_force"},
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_panels_only_for_what_a_run_has(replays, case):
    """A collision in zero gravity gets no height panel (no plane) and no potential energy
    (zero throughout: its kinetic energy is the total); a drop no momentum panel; each panel
    holds only the runs that have its quantity."""
    blueprint, static, _ = replays[case]
    plots = _plots(blueprint)
    assert set(plots) == PANELS[case]
    for family, view in plots.items():
        for content in view.contents:
            prefix = content.removeprefix("+ ").split("/series/")[0]
            assert any(p.startswith(f"{prefix}/series/{family}/") for p in static), content
    if case == "collision":
        energy = _lines(static, "energy")
        assert [name for name, _ in energy.values()] == ["kinetic = total"]
        assert "energy (J): kinetic = total" in [v.name for v in _views(blueprint)]
    if case == "drop":
        names = {name for name, _ in _lines(static, "energy").values()}
        assert names == {"kinetic", "potential", "total"}


@pytest.mark.parametrize("case", sorted(CASES))
def test_every_plot_shares_one_time_axis_and_the_colours_background(replays, case):
    blueprint, _, _ = replays[case]
    background = int.from_bytes(bytes([*style.PLOT_BACKGROUND, 255]), "big")
    for view in _plots(blueprint).values():
        assert _prop(view, "TimeAxis", "link") == [rrb.components.LinkAxis.LinkToGlobal.value]
        assert _prop(view, "PlotBackground", "color") == [background]


@pytest.mark.parametrize("case", sorted(CASES))
def test_series_colours_stand_out_and_say_one_thing_each(replays, case):
    """Every line stands at least 3:1 (WCAG 2.1, graphics) against the plots' background; a
    run alone colours a body as in 3D (lifted if too dark) in every plot, energy by kind;
    among runs, each run has one colour in every plot, and no two runs share one."""
    _, static, _ = replays[case]
    lines = _lines(static)
    assert lines
    for path, (_, color) in lines.items():
        assert style.contrast(color, style.PLOT_BACKGROUND) >= WCAG_GRAPHICS, path
    runs = [load_log(LOGS[n]) for n in CASES[case]]
    if len(runs) > 1:
        by_run = {
            run.run_id: {c for p, (_, c) in lines.items() if p.startswith(run_prefix(run.run_id))}
            for run in runs
        }
        assert all(len(colors) == 1 for colors in by_run.values()), by_run
        assert len(set.union(*by_run.values())) == len(runs)
        return
    (run,) = runs
    for body, rgba in body_rgba(run).items():
        want = style.readable([round(255 * c) for c in rgba])
        mine = {c for p, (name, c) in lines.items() if name.endswith(f" {body}")}
        if case != "box":  # the box's velocity has several axes: coloured by axis
            assert mine == {want}, body
    for kind, color in style.ENERGY.items():
        drawn = [c for p, (_, c) in _lines(static, "energy").items() if p.endswith(kind)]
        assert drawn in ([], [style.readable(color)])


def test_a_dark_colour_is_lifted_towards_white_until_it_stands_out():
    for dark in [(0, 0, 0), (0, 0, 255), (40, 0, 60), (20, 22, 26), (120, 0, 0)]:
        lifted = style.readable(dark)
        assert style.contrast(lifted, style.PLOT_BACKGROUND) >= WCAG_GRAPHICS
        k = [(c - c0) / (255 - c0) for c, c0 in zip(lifted, dark, strict=True) if c0 < 255]
        assert max(k) - min(k) < 2 / 255 and 0 < k[0] <= 1  # a mix with white: the same hue
    assert style.readable((230, 159, 0)) == (230, 159, 0)  # readable already: unchanged
    assert style.contrast((255, 255, 255), (0, 0, 0)) == pytest.approx(21.0)
    assert style.contrast((119, 119, 119), (255, 255, 255)) == pytest.approx(4.48, abs=0.01)


@pytest.mark.parametrize("case", ["collision", "several"])
def test_a_conserved_momentum_reads_flat(replays, case):
    """The collision's total momentum is conserved (to 1e-15): its plot spans at least the
    bodies' own momenta (1 kg x 2 m/s, 1 kg x -1 m/s: +-2 kg m/s), alone
    (where the bodies' m v are drawn too) and among runs (only the sum), so the sum reads as
    the flat line it is instead of rounding noise stretched over the plot."""
    blueprint, _, samples = replays[case]
    ((lo, hi),) = _prop(_plots(blueprint)["momentum"], "ScalarAxis", "range")
    assert lo <= -2.0 and hi >= 2.0
    (total,) = [
        v for p, (_, v) in samples.items() if p.endswith("collision-a2303a32/series/momentum/px")
    ]
    np.testing.assert_allclose(total, 1.0, atol=1e-12)
    assert np.ptp(total) < 1e-9 * (hi - lo)


@pytest.mark.parametrize("case", sorted(CASES))
def test_legends_cover_no_data_and_titles_fit(replays, case):
    """A legend is shown only where its colours tell its series apart, in a corner whose box
    (the size the layout reserves for it at 1600 x 940 px) holds no sample of the plot's
    series; a plot with one series names it in its title instead; no title is cut."""
    blueprint, static, samples = replays[case]
    plots = _plots(blueprint)
    series = samples
    t0 = min(t.min() for t, _ in series.values())  # the time axis all plots share
    t1 = max(t.max() for t, _ in series.values())
    rows = math.ceil(len(plots) / layout.COLUMNS)
    plot_w = layout.SCREEN_PX[0] * layout.PLOTS_SHARE / layout.COLUMNS - 40
    plot_h = layout.SCREEN_PX[1] / rows - 50
    for view in _views(blueprint):
        assert len(str(view.name)) <= layout.MAX_TITLE, view.name
    for family, view in plots.items():
        mine = {p: s for p, s in series.items() if f"/series/{family}/" in p}
        named = {  # the legend's entries: one per name (the viewer merges equal names)
            static[p][f"{kind}:names"][0]: static[p][f"{kind}:colors"][0]
            for p in mine
            for kind in ("SeriesLines", "SeriesPoints")
            if f"{kind}:names" in static[p]
        }
        if _prop(view, "PlotLegend", "visible") == [False]:
            continue
        (only, *more) = named
        assert more or len(f"{view.name}: {only}") > layout.MAX_TITLE  # else in the title
        assert len(set(named.values())) == len(named)  # its colours tell the series apart
        (corner,) = _prop(view, "PlotLegend", "corner")
        name = rrb.components.Corner2D(corner).name
        ((lo, hi),) = _prop(view, "ScalarAxis", "range")
        h = (layout.LEGEND_PAD_PX + layout.LEGEND_ROW_PX * len(named)) / plot_h
        w = (layout.LEGEND_PAD_PX + 24 + layout.CHAR_PX * max(map(len, named))) / plot_w
        x = (t0, t0 + w * (t1 - t0)) if name.startswith("Left") else (t1 - w * (t1 - t0), t1)
        y = (hi - h * (hi - lo), hi) if name.endswith("Top") else (lo, lo + h * (hi - lo))
        for path, (t, v) in mine.items():
            inside = (t >= x[0]) & (t <= x[1]) & (v >= y[0]) & (v <= y[1])
            assert not inside.any(), (family, path, name)
