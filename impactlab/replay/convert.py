"""Log one decoded run into a Rerun recording, column by column, under ``/runs/<run_id>``.

Entities of a run (P = ``/runs/<run_id>``), all on the duration timeline ``sim_time``:

| entity                                 | what                                            |
|----------------------------------------|-------------------------------------------------|
| P/world/static/<geom>                  | static geoms, the ground (`replay.geoms`)       |
| P/world/bodies/<body>                  | pose (Transform3D); children: its geoms, a      |
|                                        | ball's spin marker (`replay.geoms`)             |
| P/world/trails/<body>                  | centre positions (Points3D; the view shows the  |
|                                        | last `TRAIL_S` seconds)                         |
| P/world/velocity/<body>                | velocity arrow, length = v * `VELOCITY_ARROW_S` |
| P/world/contacts/points, .../force     | contact points and force on geom2 (scaled)      |
| P/series/height/<body>                 | height of its lowest point above the ground, m  |
| P/series/velocity/<body>/<vx..vz>      | velocity components that are not all zero, m/s  |
| P/series/energy/<kinetic..total>       | MuJoCo's energy, J                              |
| P/series/momentum/<px..pz>             | sum of m v (runs with several bodies), kg m/s   |
| P/series/contact_force/<pair>[/impacts, /releases] | a touching pair's summed normal     |
|                                        | force, N (zero without contact); event markers  |
| P/events/contacts, P/events/log        | impact / release texts; the log's own events    |
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import polars as pl
import rerun as rr

from impactlab.logs.geoms import ModelScene, body_rgba
from impactlab.logs.load import RunLog
from impactlab.replay.events import Event, pairs
from impactlab.replay.geoms import body_path, geom_extents, log_model, model_scene, rgba255

TIMELINE = "sim_time"
TRAIL_S = 0.25
VELOCITY_ARROW_S = 0.1
CONTACT_COLOR = (255, 200, 0)
IMPACT_COLOR = (230, 30, 30)
RELEASE_COLOR = (30, 160, 30)
ENERGY_COLORS = {"kinetic": (60, 140, 255), "potential": (240, 160, 30), "total": (230, 230, 230)}
PAIR_COLOR = (220, 220, 220)
LOG_LEVELS = {"WARNING": "WARN", "FATAL": "CRITICAL", "UNKNOWN": "INFO"}


@dataclass
class LoggedRun:
    """What `log_run` wrote for one run; the blueprint is laid out from it."""

    run_id: str
    prefix: str
    bodies: list[str]
    families: list[str] = field(default_factory=list)  # series families under P/series
    bounds: tuple[np.ndarray, np.ndarray] = (np.full(3, -0.5), np.full(3, 0.5))  # m, (3,) each
    momentum_scale: float = 0.0  # kg m/s: the largest |m v| component of one body


def run_prefix(run_id: str) -> str:
    """The entity subtree of a run: ``/runs/<run_id>`` (escaped)."""
    return f"/runs/{rr.escape_entity_path_part(run_id)}"


def time_base(run: RunLog) -> np.ndarray:
    """The logged steps' times, ns, (nstep,): the body frames' (or the energy's) t_ns."""
    frame = next(iter(run.bodies.values()), run.energy)
    return frame["t_ns"].to_numpy().astype(np.int64)


def log_run(
    rec: rr.RecordingStream, run: RunLog, events: Sequence[Event], *, label: str = ""
) -> LoggedRun:
    """Log everything of one run.

    `label` prefixes series names to tell runs apart in one recording; series then get the
    viewer's automatic colours instead of the bodies' (which every run shares).
    """
    prefix = run_prefix(run.run_id)
    t_ns = time_base(run)
    scene = model_scene(run)
    logged = LoggedRun(run.run_id, prefix, list(run.bodies), bounds=scene_bounds(run, scene))
    rec.log(f"{prefix}/world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    log_model(rec, run, scene, prefix, logged.bounds, body_colors(run))
    _log_bodies(rec, run, prefix, t_ns)
    _log_flexes(rec, run, scene, prefix, t_ns)
    _log_contacts(rec, run, prefix, t_ns)
    logged.families = _log_series(rec, run, prefix, t_ns, events, label)
    logged.momentum_scale = momentum_scale(run)
    _log_events(rec, run, prefix, events)
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


def momentum_scale(run: RunLog) -> float:
    """The largest |m v| component of any one body over the run (kg m/s; 0 when none)."""
    info = run.body_info
    scales = [
        float(np.max(np.abs(frame.select("vx", "vy", "vz").to_numpy()))) * info[name].mass
        for name, frame in run.bodies.items()
        if name in info and frame.height
    ]
    finite = [x for x in scales if np.isfinite(x)]
    return max(finite, default=0.0)


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
        body = body_path(prefix, name)
        rec.send_columns(
            body,
            indexes=[times],
            columns=rr.Transform3D.columns(translation=pos, quaternion=quat_xyzw),
        )
        part = rr.escape_entity_path_part(name)
        trail = f"{prefix}/world/trails/{part}"
        rec.send_columns(trail, indexes=[times], columns=rr.Points3D.columns(positions=pos))
        rec.log(
            trail,
            rr.Points3D.from_fields(radii=[radius * 0.05], colors=[colors[name]]),
            static=True,
        )
        arrows = f"{prefix}/world/velocity/{part}"
        rec.send_columns(
            arrows,
            indexes=[times],
            columns=rr.Arrows3D.columns(origins=pos, vectors=vel * VELOCITY_ARROW_S),
        )
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
    rec.send_columns(
        f"{prefix}/world/contacts/points",
        indexes=[times],
        columns=rr.Points3D.columns(positions=data[:, :3]).partition(lengths),
    )
    rec.log(
        f"{prefix}/world/contacts/points",
        rr.Points3D.from_fields(radii=[0.01], colors=[CONTACT_COLOR]),
        static=True,
    )
    rec.send_columns(
        f"{prefix}/world/contacts/force",
        indexes=[times],
        columns=rr.Arrows3D.columns(origins=data[:, :3], vectors=force * scale).partition(lengths),
    )
    rec.log(
        f"{prefix}/world/contacts/force",
        rr.Arrows3D.from_fields(colors=[CONTACT_COLOR]),
        static=True,
    )


def _series(
    rec: rr.RecordingStream,
    path: str,
    t_ns: np.ndarray,
    values: np.ndarray,
    name: str,
    color: Sequence[int] | None = None,
) -> None:
    rec.send_columns(
        path,
        indexes=[_times(t_ns)],
        columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64)),
    )
    style = rr.SeriesLines(names=name, colors=[color] if color is not None else None)
    rec.log(path, style, static=True)


def _markers(
    rec: rr.RecordingStream,
    path: str,
    t_ns: np.ndarray,
    values: np.ndarray,
    name: str,
    color: Sequence[int],
) -> None:
    if t_ns.size == 0:
        return
    rec.send_columns(
        path, indexes=[_times(t_ns)], columns=rr.Scalars.columns(scalars=values.astype(float))
    )
    rec.log(path, rr.SeriesPoints(names=name, colors=[color], marker_sizes=[5.0]), static=True)


def _log_series(
    rec: rr.RecordingStream,
    run: RunLog,
    prefix: str,
    t_ns: np.ndarray,
    events: Sequence[Event],
    label: str,
) -> list[str]:
    """The time series; returns the families logged (gap, normal_velocity, ...)."""
    families: set[str] = set()
    series = f"{prefix}/series"
    colors = {} if label else body_colors(run)
    force = _normal_force(run, t_ns)
    for pair in pairs(run):
        part = rr.escape_entity_path_part(pair.name)
        pair_force = force.get((pair.first, pair.second), np.zeros(t_ns.size))
        path = f"{series}/contact_force/{part}"
        color = colors.get(pair.second) if pair.first not in run.bodies else None
        _series(rec, path, t_ns, pair_force, f"{label}F_n {pair.name}", color)
        for kind, mark_color in (("impact", IMPACT_COLOR), ("release", RELEASE_COLOR)):
            steps = np.array([e.step for e in events if e.kind == kind and e.pair == pair], int)
            values = pair_force[steps]
            _markers(rec, f"{path}/{kind}s", t_ns[steps], values, f"{label}{kind}", mark_color)
        families.add("contact_force")
    if run.clearance.height:
        lowest = run.clearance.group_by("body", "t_ns").agg(pl.col("clearance_m").min())
        for (name,), frame in lowest.sort("t_ns").group_by(["body"], maintain_order=True):
            body = rr.escape_entity_path_part(str(name))
            values = frame["clearance_m"].to_numpy()
            path = f"{series}/height/{body}"
            _series(
                rec,
                path,
                frame["t_ns"].to_numpy(),
                values,
                f"{label}height {name}",
                colors.get(str(name)),
            )
            families.add("height")
    masses = run.body_info
    momentum = np.zeros((t_ns.size, 3))
    for name, frame in run.bodies.items():
        vel = frame.select("vx", "vy", "vz").to_numpy()
        momentum += vel * (masses[name].mass if name in masses else 0.0)
        body = rr.escape_entity_path_part(name)
        for i, comp in enumerate(("vx", "vy", "vz")):
            if np.any(vel[:, i] != 0):
                path = f"{series}/velocity/{body}/{comp}"
                _series(rec, path, t_ns, vel[:, i], f"{label}{comp} {name}", colors.get(name))
                families.add("velocity")
    if len(run.bodies) > 1:
        for i, comp in enumerate(("px", "py", "pz")):
            if np.any(momentum[:, i] != 0) or i == 0:
                _series(rec, f"{series}/momentum/{comp}", t_ns, momentum[:, i], f"{label}{comp}")
        families.add("momentum")
    if not run.energy.is_empty():
        t_energy = run.energy["t_ns"].to_numpy()
        for comp, color in ENERGY_COLORS.items():
            values = run.energy[comp].to_numpy()
            path = f"{series}/energy/{comp}"
            _series(rec, path, t_energy, values, f"{label}{comp}", None if label else color)
        families.add("energy")
    order = ("height", "velocity", "energy", "momentum", "contact_force")
    return [f for f in order if f in families]


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


def _log_events(rec: rr.RecordingStream, run: RunLog, prefix: str, events: Sequence[Event]) -> None:
    """Impact / release texts at P/events/contacts, the log's own events at P/events/log."""
    if events:
        rec.send_columns(
            f"{prefix}/events/contacts",
            indexes=[_times(np.array([e.t_ns for e in events], np.int64))],
            columns=[
                *rr.TextLog.columns(text=[e.text for e in events], level=["INFO"] * len(events)),
                *rr.AnyValues.columns(details=[e.details for e in events]),
            ],
        )
    if not run.events.is_empty():
        levels = [LOG_LEVELS.get(level, level) for level in run.events["level"].to_list()]
        rec.send_columns(
            f"{prefix}/events/log",
            indexes=[_times(run.events["t_ns"].to_numpy())],
            columns=rr.TextLog.columns(text=run.events["message"].to_list(), level=levels),
        )
