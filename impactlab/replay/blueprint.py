"""The default layout of a replay: 3D scene and event log on the left, time series on the right."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from impactlab.replay import style
from impactlab.replay.convert import TIMELINE, TRAIL_S, LoggedRun, Series

TITLES = {
    "height": "height above the ground (m)",
    "velocity": "velocity (m/s)",
    "energy": "energy (J)",
    "momentum": "momentum m v (kg m/s)",
    "contact_force": "contact force (N)",
}
COLUMNS = 2  # of time series views
PLOTS_SHARE = 0.6  # of the width
SCREEN_PX = (1600, 940)  # the viewer's area the legends are placed for (a laptop's screen)
MAX_TITLE = 46  # characters a view's title shows uncut at that size
LEGEND_ROW_PX, LEGEND_PAD_PX, CHAR_PX = 21, 30, 7.5  # the pad: the box's and its margin
MAX_LEGEND = 0.5  # of a plot's height: a longer legend is hidden (names show on hover)


def replay_blueprint(runs: Sequence[LoggedRun]) -> rrb.Blueprint:
    """The layout for one or several logged runs: one 3D view per run side by side, one
    time series view per quantity a run has (each overlaying the runs), all on one time axis."""
    scenes = [_scene_view(run, name=run.label or "3D") for run in runs]
    scene = scenes[0] if len(scenes) == 1 else rrb.Grid(*scenes, name="runs")
    events = rrb.TextLogView(
        name="events",
        origin="/runs",
        contents=[f"+ {run.prefix}/events/**" for run in runs],
        columns=rrb.archetypes.TextLogColumns(text_log_columns=["Body", "LogLevel", "EntityPath"]),
    )
    series = [s for run in runs for s in run.series]
    families = [f for f in TITLES if any(s.family == f for s in series)]
    rows = max(1, math.ceil(len(families) / COLUMNS))
    plot_px = (SCREEN_PX[0] * PLOTS_SHARE / COLUMNS - 40, SCREEN_PX[1] / rows - 50)
    times = np.concatenate([s.t_ns for s in series] or [np.zeros(1)])
    t_range = (float(times.min()), float(times.max()))
    views = [
        _series_view(f, runs, [s for s in series if s.family == f], t_range, plot_px)
        for f in families
    ]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(scene, events, row_shares=[3, 1]),
            rrb.Grid(*views, grid_columns=COLUMNS),
            column_shares=[1 - PLOTS_SHARE, PLOTS_SHARE],
        ),
        rrb.TimePanel(timeline=TIMELINE, state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )


def _scene_view(run: LoggedRun, *, name: str) -> rrb.Spatial3DView:
    trail = rrb.VisibleTimeRanges(
        rrb.VisibleTimeRange(
            TIMELINE,
            start=rrb.TimeRangeBoundary.cursor_relative(seconds=-TRAIL_S),
            end=rrb.TimeRangeBoundary.cursor_relative(),
        )
    )
    lo, hi = run.bounds
    centre = (lo + hi) / 2
    distance = 1.1 * max(float(np.max(hi - lo)), 0.5)
    eye = rrb.EyeControls3D(
        position=centre + distance * np.array([0.25, -1.0, 0.3]),
        look_target=centre,
        eye_up=[0.0, 0.0, 1.0],
    )
    return rrb.Spatial3DView(
        name=name,
        origin=f"{run.prefix}/world",
        eye_controls=eye,
        overrides={
            f"{run.prefix}/world/trails/{rr.escape_entity_path_part(body)}": trail
            for body in run.bodies
        },
    )


def _series_view(
    family: str,
    runs: Sequence[LoggedRun],
    series: Sequence[Series],
    t_range: tuple[float, float],
    plot_px: tuple[float, float],
) -> rrb.TimeSeriesView:
    """One quantity's plot: a title that names a lone series (no legend then), else a legend
    in the corner where it covers no data (the y range grows to make room), none when its
    colours repeat (it could not tell those series apart); a y range from zero (and -scale
    to +scale: a conserved sum reads flat, not as rounding noise) to the data; the time axis
    shared with every other plot; the background the colours were chosen against."""
    named = {s.name: s.color for s in series if s.name}  # one entry per name, as the viewer
    title = TITLES[family]
    if len(named) == 1 and len(title) + len(next(iter(named))) + 2 <= MAX_TITLE:
        title, named = f"{title}: {next(iter(named))}", {}
    scale = max(s.scale for s in series)
    values = np.concatenate([s.values for s in series] + [np.array([-scale, scale])])
    values = values[np.isfinite(values)]
    lo, hi = float(values.min()), float(values.max())
    pad = 0.05 * (hi - lo) if hi > lo else 1.0
    lo, hi = lo - pad, hi + pad
    legend = rrb.PlotLegend(visible=False)
    height = (LEGEND_PAD_PX + LEGEND_ROW_PX * len(named)) / plot_px[1]
    if named and len(set(named.values())) == len(named) and height <= MAX_LEGEND:
        width = (LEGEND_PAD_PX + 24 + CHAR_PX * max(map(len, named))) / plot_px[0]
        corner, lo, hi = _legend_corner(series, (width, height), t_range, (lo, hi))
        legend = rrb.PlotLegend(corner, visible=True)
    return rrb.TimeSeriesView(
        name=title,
        origin="/runs",
        contents=[
            f"+ {run.prefix}/series/{family}/**"
            for run in runs
            if any(s.family == family for s in run.series)
        ],
        axis_x=rrb.TimeAxis(link="LinkToGlobal"),
        axis_y=rrb.ScalarAxis(range=(lo, hi), zoom_lock=False),
        plot_legend=legend,
        background=rrb.archetypes.PlotBackground(color=style.PLOT_BACKGROUND, show_grid=True),
    )


def _legend_corner(
    series: Sequence[Series],
    size: tuple[float, float],
    t_range: tuple[float, float],
    y_range: tuple[float, float],
) -> tuple[rrb.components.Corner2D, float, float]:
    """The corner whose legend box (`size`: fractions of the plot's width and height) needs
    the least extra y range to cover no data, and that y range."""
    (w, h), (t0, t1), (lo, hi) = size, t_range, y_range
    options = []
    for corner in rrb.components.Corner2D:
        left, top = corner.name.startswith("Left"), corner.name.endswith("Top")
        cut = t0 + w * (t1 - t0) if left else t1 - w * (t1 - t0)
        near = [s.values[(s.t_ns <= cut) if left else (s.t_ns >= cut)] for s in series]
        under = np.concatenate(near)
        under = under[np.isfinite(under)]
        new_lo, new_hi = lo, hi
        if under.size and top:
            new_hi = max(hi, (float(under.max()) - h * lo) / (1 - h))
        elif under.size:
            new_lo = min(lo, (float(under.min()) - h * hi) / (1 - h))
        options.append((new_hi - new_lo, corner.value, corner, new_lo, new_hi))
    _, _, corner, lo, hi = min(options)
    return corner, lo, hi
