"""The default layout of a replay: 3D scene and event log on the left, time series on the right.

With several runs in one recording, the 3D views sit side by side (one per run) and every
time series view overlays the runs, so a sweep can be compared at a glance.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from impactlab.replay.convert import TIMELINE, TRAIL_S, LoggedRun

SERIES_TITLES = {
    "height": "height above the ground (m)",
    "velocity": "velocity (m/s)",
    "energy": "energy (J)",
    "momentum": "momentum, sum of m v (kg m/s)",
    "contact_force": "contact normal force (N); impacts, releases",
}


def replay_blueprint(runs: Sequence[LoggedRun]) -> rrb.Blueprint:
    """The layout for one or several logged runs."""
    scenes = [_scene_view(run, name=run.run_id if len(runs) > 1 else "3D") for run in runs]
    scene = scenes[0] if len(scenes) == 1 else rrb.Grid(*scenes, name="runs")
    events = rrb.TextLogView(
        name="events",
        origin="/runs",
        contents=[f"+ {run.prefix}/events/**" for run in runs],
    )
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(scene, events, row_shares=[3, 1]),
            rrb.Vertical(*_series_views(runs)),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline=TIMELINE),
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


def _series_views(runs: Sequence[LoggedRun]) -> list[rrb.TimeSeriesView]:
    views = []
    for family, title in SERIES_TITLES.items():
        if title is None or not any(family in run.families for run in runs):
            continue
        contents = [f"+ {run.prefix}/series/{family}/**" for run in runs]
        axis = _momentum_axis(runs) if family == "momentum" else None
        views.append(rrb.TimeSeriesView(name=title, origin="/runs", contents=contents, axis_y=axis))
    return views


def _momentum_axis(runs: Sequence[LoggedRun]) -> rrb.ScalarAxis | None:
    """A fixed y range of +-1.1 x the largest |m v| of one body: a conserved momentum then
    reads as the flat line it is, not as rounding noise (1e-12) stretched over the plot."""
    scale = max((run.momentum_scale for run in runs), default=0.0)
    if not scale > 0:
        return None
    return rrb.ScalarAxis(range=(-1.1 * scale, 1.1 * scale), zoom_lock=False)
