"""Log one decoded run into a Rerun recording, column by column, under ``/runs/<run_id>``."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import polars as pl
import rerun as rr

from impactlab.logs.geoms import ModelScene, body_rgba
from impactlab.logs.load import RunLog
from impactlab.replay import style
from impactlab.replay.events import Event, pairs
from impactlab.replay.geoms import body_path, geom_extents, log_model, model_scene, rgba255

TIMELINE = "sim_time"
TRAIL_S = 0.25
VELOCITY_ARROW_S = 0.1
LOG_LEVELS = {"WARNING": "WARN", "FATAL": "CRITICAL", "UNKNOWN": "INFO"}


@dataclass(frozen=True)
class Series:
    """A time series a run logged under P/series/<family>: its legend name, colour (0-255
    RGB), times (ns) and values, both (n,); `scale`: the size its values are read against
    (the bodies' momenta for their sum: its plot spans +-scale)."""

    family: str
    name: str
    color: style.Rgb
    t_ns: np.ndarray
    values: np.ndarray
    scale: float = 0.0


@dataclass
class LoggedRun:
    """What `log_run` wrote for one run; the blueprint is laid out from it."""

    run_id: str
    prefix: str
    bodies: list[str]
    label: str = ""  # the run among others (its sweep point); "" alone
    series: list[Series] = field(default_factory=list)
    bounds: tuple[np.ndarray, np.ndarray] = (np.full(3, -0.5), np.full(3, 0.5))  # m, (3,) each


def run_prefix(run_id: str) -> str:
    """The entity subtree of a run: ``/runs/<run_id>`` (escaped)."""
    return f"/runs/{rr.escape_entity_path_part(run_id)}"


def log_run(
    rec: rr.RecordingStream,
    run: RunLog,
    events: Sequence[Event],
    *,
    label: str = "",
    color: style.Rgb | None = None,
) -> LoggedRun:
    """Log everything of one run.

    Among several runs in one recording, `label` names the run (its series are prefixed
    ``label: ``) and `color` is its colour in every plot; a run alone colours its series by
    quantity and body, as its bodies are drawn.
    """
    prefix = run_prefix(run.run_id)
    t_ns = next(iter(run.bodies.values()), run.energy)["t_ns"].to_numpy()  # the logged steps'
    scene = model_scene(run)
    logged = LoggedRun(run.run_id, prefix, list(run.bodies), label, bounds=scene_bounds(run, scene))
    rec.log(f"{prefix}/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    log_model(rec, run, scene, prefix, logged.bounds)
    _log_bodies(rec, run, prefix, t_ns)
    _log_flexes(rec, run, scene, prefix, t_ns)
    _log_contacts(rec, run, prefix, t_ns)
    logged.series = _log_series(rec, run, prefix, t_ns, events, label, color)
    _log_events(rec, run, prefix, events, label)
    return logged


def scene_bounds(run: RunLog, scene: ModelScene | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Corners (m, (3,) each) of the box every body's surface stays in, plane level and the
    static geoms (but planes) included."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    info = run.body_info
    extents = geom_extents(scene) if scene is not None else {}
    for name, frame in run.bodies.items():
        pos = frame.select("x", "y", "z").to_numpy()
        r = extents.get(name) or (info[name].radius if name in info else None) or 0.0
        if pos.size:
            lo, hi = np.minimum(lo, pos.min(axis=0) - r), np.maximum(hi, pos.max(axis=0) + r)
    for g in scene.geoms if scene is not None else ():
        if g.body == "world" and g.type != "plane" and g.visible:
            r = extents.get("world", 0.0) if g.mesh else float(np.linalg.norm(g.size))
            lo, hi = np.minimum(lo, np.asarray(g.pos) - r), np.maximum(hi, np.asarray(g.pos) + r)
    if run.plane_z is not None:
        lo[2], hi[2] = min(lo[2], run.plane_z), max(hi[2], run.plane_z)
    if not np.all(np.isfinite(lo)):
        return np.full(3, -0.5), np.full(3, 0.5)
    return lo, hi


def _times(t_ns: np.ndarray) -> rr.TimeColumn:
    return rr.TimeColumn(TIMELINE, duration=np.asarray(t_ns, np.int64).astype("timedelta64[ns]"))


def body_colors(run: RunLog) -> dict[str, tuple[int, int, int]]:
    """Each body's colour (0-255 RGB), as the log gives it (`impactlab.logs.geoms`)."""
    return {name: rgba255(rgba)[:3] for name, rgba in body_rgba(run).items()}  # type: ignore[misc]


def _log_bodies(rec: rr.RecordingStream, run: RunLog, prefix: str, t_ns: np.ndarray) -> None:
    """Pose, trail points and velocity arrow of each body (its geoms: `replay.geoms`)."""
    times = _times(t_ns)
    colors = body_colors(run)
    info = run.body_info
    for name, frame in run.bodies.items():
        state = frame.select("x", "y", "z", "qx", "qy", "qz", "qw", "vx", "vy", "vz").to_numpy()
        pos, quat_xyzw, vel = state[:, :3], state[:, 3:7], state[:, 7:]
        radius = (info[name].radius if name in info else None) or 0.05
        pose = rr.Transform3D.columns(translation=pos, quaternion=quat_xyzw)
        rec.send_columns(body_path(prefix, name), indexes=[times], columns=pose)
        part = rr.escape_entity_path_part(name)
        trail = f"{prefix}/world/trails/{part}"
        rec.send_columns(trail, indexes=[times], columns=rr.Points3D.columns(positions=pos))
        dots = rr.Points3D.from_fields(radii=[radius * 0.05], colors=[colors[name]])
        rec.log(trail, dots, static=True)
        arrows = f"{prefix}/world/velocity/{part}"
        moving = rr.Arrows3D.columns(origins=pos, vectors=vel * VELOCITY_ARROW_S)
        rec.send_columns(arrows, indexes=[times], columns=moving)
        rec.log(arrows, rr.Arrows3D.from_fields(colors=[colors[name]]), static=True)


def _log_flexes(
    rec: rr.RecordingStream, run: RunLog, scene: ModelScene, prefix: str, t_ns: np.ndarray
) -> None:
    """Each flex as a mesh (or line segments) through its vertex bodies' logged positions."""
    for flex in scene.flexes:
        frames = [run.bodies.get(b) for b in flex.bodies]
        if any(f is None or f.height != t_ns.size for f in frames):
            continue  # a damaged log: the flex is not drawn
        xyz = np.stack([f.select("x", "y", "z").to_numpy() for f in frames if f is not None], 1)
        path = f"{prefix}/world/flexes/{rr.escape_entity_path_part(flex.name)}"
        cells = np.array(flex.cells, dtype=np.uint32)
        color = rgba255(flex.rgba)
        n = len(flex.bodies)
        if cells.shape[1] == 3:
            rec.log(
                path,
                rr.Mesh3D.from_fields(triangle_indices=cells, vertex_colors=[color]),
                static=True,
            )
            columns = rr.Mesh3D.columns(vertex_positions=xyz.reshape(-1, 3))
        else:  # a 1D flex: its segments
            rec.log(path, rr.LineStrips3D.from_fields(colors=[color]), static=True)
            columns = rr.LineStrips3D.columns(strips=xyz[:, cells].reshape(-1, 2, 3))
            n = len(cells)
        rec.send_columns(path, indexes=[_times(t_ns)], columns=columns.partition([n] * t_ns.size))


def _log_contacts(rec: rr.RecordingStream, run: RunLog, prefix: str, t_ns: np.ndarray) -> None:
    """Contact points and force arrows on the steps in contact; cleared on the step after."""
    contacts = run.contacts.sort("t_ns", maintain_order=True)
    if contacts.is_empty() or t_ns.size == 0:
        return
    data = contacts.select("x", "y", "z", "fx", "fy", "fz").to_numpy()
    step = np.searchsorted(t_ns, contacts["t_ns"].to_numpy())
    keep = step < t_ns.size
    data, step = data[keep], step[keep]
    counts = np.bincount(step, minlength=t_ns.size)
    touching = np.flatnonzero(counts)
    after = touching + 1
    cleared = after[(after < t_ns.size)]
    cleared = cleared[counts[cleared] == 0]
    rows = np.union1d(touching, cleared)
    lengths = counts[rows]
    force = data[:, 3:]
    largest = float(np.max(np.linalg.norm(force, axis=1), initial=0.0))
    radii = [b.radius for b in run.body_info.values() if b.radius]
    scale = (2 * max(radii, default=0.1)) / largest if largest > 0 else 0.0
    times = _times(t_ns[rows])
    points, arrows = f"{prefix}/world/contacts/points", f"{prefix}/world/contacts/force"
    at_points = rr.Points3D.columns(positions=data[:, :3]).partition(lengths)
    rec.send_columns(points, indexes=[times], columns=at_points)
    rec.log(points, rr.Points3D.from_fields(radii=[0.01], colors=[style.CONTACT]), static=True)
    forces = rr.Arrows3D.columns(origins=data[:, :3], vectors=force * scale).partition(lengths)
    rec.send_columns(arrows, indexes=[times], columns=forces)
    rec.log(arrows, rr.Arrows3D.from_fields(colors=[style.CONTACT]), static=True)


def _log_series(
    rec: rr.RecordingStream,
    run: RunLog,
    prefix: str,
    t_ns: np.ndarray,
    events: Sequence[Event],
    label: str,
    run_color: style.Rgb | None,
) -> list[Series]:
    """The time series under P/series, each only when the run has it (no series that is zero
    throughout); returns what was logged."""
    logged: list[Series] = []
    bodies = body_colors(run)

    def plot(
        family: str,
        parts: Sequence[str],
        name: str,
        t: np.ndarray,
        values: np.ndarray,
        color: style.Rgb,
        marker: rr.components.MarkerShape | None = None,
        scale: float = 0.0,
    ) -> None:
        path = "/".join([f"{prefix}/series/{family}", *map(rr.escape_entity_path_part, parts)])
        values = np.asarray(values, dtype=np.float64)
        rec.send_columns(path, indexes=[_times(t)], columns=rr.Scalars.columns(scalars=values))
        if marker is not None:  # an event marker on its pair's line, one legend entry for all
            rec.log(
                path,
                rr.SeriesPoints(names=name, colors=[color], markers=[marker], marker_sizes=[6.0]),
                static=True,
            )
        else:
            name = f"{label}: {name}" if label else name
            color = style.readable(run_color or color)
            lines = rr.SeriesLines(names=name, colors=[color], aggregation_policy="MinMax")
            rec.log(path, lines, static=True)  # MinMax: a zoomed-out spike keeps its peak
        logged.append(Series(family, name, color, t, values, scale))

    force = _normal_force(run, t_ns)
    for i, pair in enumerate(pairs(run)):
        values = force.get((pair.first, pair.second), np.zeros(t_ns.size))
        color = style.CONTACT if i == 0 else style.PALETTE[i % len(style.PALETTE)]
        plot("contact_force", [pair.name], f"F_n {pair.name}", t_ns, values, color)
        for kind, mark, shape in (
            ("impact", style.IMPACT, rr.components.MarkerShape.Down),
            ("release", style.RELEASE, rr.components.MarkerShape.Up),
        ):
            at = np.array([e.t_ns for e in events if e.kind == kind and e.pair == pair], np.int64)
            if at.size and t_ns.size:
                on_line = np.interp(at, t_ns, values)
                plot("contact_force", [pair.name, f"{kind}s"], kind, at, on_line, mark, shape)
    if run.clearance.height:
        lowest = run.clearance.group_by("body", "t_ns").agg(pl.col("clearance_m").min())
        for (name,), frame in lowest.sort("t_ns").group_by(["body"], maintain_order=True):
            color = bodies.get(str(name), style.PALETTE[0])
            values = frame["clearance_m"].to_numpy()
            plot("height", [str(name)], str(name), frame["t_ns"].to_numpy(), values, color)
    vel = {name: frame.select("vx", "vy", "vz").to_numpy() for name, frame in run.bodies.items()}
    moving = {name: [i for i in range(3) if np.any(v[:, i] != 0)] for name, v in vel.items()}
    by_axis = any(len(axes) > 1 for axes in moving.values())  # else by body
    for name, axes in moving.items():
        for i in axes:
            axis = "xyz"[i]
            color = style.AXES[axis] if by_axis else bodies[name]
            plot("velocity", [name, f"v{axis}"], f"v{axis} {name}", t_ns, vel[name][:, i], color)
    if len(run.bodies) > 1:  # each body's m v (a run alone) and their sum
        info = run.body_info
        mv = {name: v * (info[name].mass if name in info else 0.0) for name, v in vel.items()}
        total = np.sum(list(mv.values()), axis=0)
        for i in range(3):
            if not any(np.any(m[:, i] != 0) for m in mv.values()):
                continue
            axis = "xyz"[i]
            for name, m in mv.items() if not label else ():
                plot("momentum", [name, f"p{axis}"], f"p{axis} {name}", t_ns, m[:, i], bodies[name])
            scale = max(float(np.max(np.abs(m[:, i]), initial=0.0)) for m in mv.values())
            color = style.ENERGY["total"]
            plot("momentum", [f"p{axis}"], f"p{axis} sum", t_ns, total[:, i], color, scale=scale)
    if not run.energy.is_empty():
        t_energy = run.energy["t_ns"].to_numpy()
        energy = {c: run.energy[c].to_numpy() for c in ("kinetic", "potential", "total")}
        alive = [c for c in ("kinetic", "potential") if np.any(energy[c] != 0)]
        if label:  # among runs: the total, one line per run
            shown = {"total": "total"} if np.any(energy["total"] != 0) else {}
        elif len(alive) == 2:
            shown = {c: c for c in energy}
        else:  # the one that is not zero throughout is the total
            shown = {c: f"{c} = total" for c in alive}
        for c, name in shown.items():
            plot("energy", [c], name, t_energy, energy[c], style.ENERGY[c])
    return logged


def _normal_force(run: RunLog, t_ns: np.ndarray) -> dict[tuple[str, str], np.ndarray]:
    """Per pair as `pairs` orders it, the summed normal force at every logged step (zeros
    between)."""
    if run.contacts.is_empty():
        return {}
    order = {(p.second, p.first): (p.first, p.second) for p in pairs(run)}
    summed = run.contacts.group_by("body1", "body2", "t_ns").agg(pl.col("normal_force").sum())
    out: dict[tuple[str, str], np.ndarray] = {}
    for (body1, body2), frame in summed.group_by("body1", "body2"):
        key = order.get((str(body1), str(body2)), (str(body1), str(body2)))
        values = np.zeros(t_ns.size)
        steps = np.searchsorted(t_ns, frame["t_ns"].to_numpy())
        ok = steps < t_ns.size
        values[steps[ok]] = frame["normal_force"].to_numpy()[ok]
        out[key] = out.get(key, 0) + values
    return out


def _log_events(
    rec: rr.RecordingStream, run: RunLog, prefix: str, events: Sequence[Event], label: str
) -> None:
    """Impact / release texts at P/events/contacts, the log's own events at P/events/log
    (each after the run's label among several runs)."""
    said = (lambda text: f"{label}: {text}") if label else (lambda text: text)
    if events:
        rec.send_columns(
            f"{prefix}/events/contacts",
            indexes=[_times(np.array([e.t_ns for e in events], np.int64))],
            columns=[
                *rr.TextLog.columns(
                    text=[said(e.text) for e in events], level=["INFO"] * len(events)
                ),
                *rr.AnyValues.columns(
                    details=[e.details for e in events],
                    e_velocity=pl.Series(
                        [e.e_velocity for e in events], dtype=pl.Float64
                    ).to_arrow(),
                ),
            ],
        )
    if not run.events.is_empty():
        levels = [LOG_LEVELS.get(level, level) for level in run.events["level"].to_list()]
        rec.send_columns(
            f"{prefix}/events/log",
            indexes=[_times(run.events["t_ns"].to_numpy())],
            columns=rr.TextLog.columns(
                text=[said(m) for m in run.events["message"].to_list()], level=levels
            ),
        )
