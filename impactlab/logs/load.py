"""Read impactlab MCAP logs into polars frames. All decoding of log files happens here.

Each channel family becomes one frame with one row per message (per contact point for
contacts), with the run's id and the time (`t_ns`, integer ns; `t_s`, float s) as columns.
Records are gathered as arrays (`records.read_mcap`) and the fixed-layout messages decoded
as whole arrays (`codec.Template`), with the protobuf library as the fallback for any
other layout. A truncated or damaged file still yields every complete message before the
damage; such a run is marked `partial`.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from google.protobuf.message import DecodeError

from impactlab.errors import LogError
from impactlab.logs import format as logformat
from impactlab.logs import messages
from impactlab.logs.decode import (
    body_state_values,
    decode_clearance,
    decode_contacts,
    decode_events,
    decode_fixed,
    empty_clearance,
    empty_contacts,
    empty_frame,
    energy_values,
    fixed_frame,
    loose_payloads,
)
from impactlab.logs.messages import BODY_FIELDS, ENERGY_FIELDS
from impactlab.logs.metadata import metadata_problem
from impactlab.logs.reader import read_mcap

UNREAD_TOPICS = frozenset({logformat.TF_TOPIC})  # poses for viewers; /bodies holds the same
DATA_SCHEMAS = frozenset(
    {
        logformat.BODY_STATE_SCHEMA,
        logformat.CONTACT_SCHEMA,
        logformat.ENERGY_SCHEMA,
        logformat.CLEARANCE_SCHEMA,
    }
)


@dataclass(frozen=True)
class BodyInfo:
    """A free body as the log's metadata describes it (kg, kg m^2 principal, m).

    `rest_height_m`: the lowest height of its centre of mass above a flat surface it touches
    (older logs: the radius of a sphere, else None); `shape`: its collision geoms' types.
    """

    name: str
    mass: float
    inertia: tuple[float, float, float]
    radius: float | None
    rest_height_m: float | None = None
    shape: str = ""
    geoms: tuple[str, ...] = ()


@dataclass(frozen=True)
class SurfaceInfo:
    """A ground surface as the log's metadata describes it (see `logs.content.SurfaceMeta`)."""

    name: str
    type: str
    level_m: float
    distance: bool


@dataclass
class RunLog:
    """One decoded log.

    Attributes:
        path: the file.
        run_id: the run's id (file stem when the metadata lacks it).
        meta: the `impactlab.run` record merged with `impactlab.outcome` (strings).
        bodies: per body name, a frame (run_id, t_ns, t_s, x .. wz), world frame, SI units.
        contacts: one row per contact point (run_id, t_ns, t_s, geom1, geom2, body1, body2,
            point, x .. fz), see `schemas/impactlab.proto`.
        energy: MuJoCo's energy (run_id, t_ns, t_s, kinetic, potential, total), J.
        events: the log's text events (run_id, t_ns, level, message).
        partial: the file is damaged or incomplete; `problems` says how.
        clearance: each body's distance to each ground surface (run_id, t_ns, t_s, body,
            surface, clearance_m); empty in logs written before it was recorded.
    """

    path: Path
    run_id: str
    meta: dict[str, str]
    bodies: dict[str, pl.DataFrame]
    contacts: pl.DataFrame
    energy: pl.DataFrame
    events: pl.DataFrame
    partial: bool = False
    problems: list[str] = field(default_factory=list)
    clearance: pl.DataFrame = field(default_factory=lambda: empty_clearance(""))

    @property
    def experiment(self) -> str:
        """The experiment's name."""
        return self.meta.get("experiment", "")

    @property
    def sweep(self) -> dict[str, Any]:
        """This run's sweep point: {dotted path: value}."""
        return json.loads(self.meta.get("sweep", "{}"))

    @property
    def sweep_point(self) -> tuple[int, int]:
        """(index, size) of this run in its sweep grid; (0, 1) without a sweep."""
        return int(self.meta.get("sweep_index", 0)), int(self.meta.get("sweep_size", 1))

    @property
    def spec(self) -> dict[str, Any]:
        """The resolved spec document the run was made from."""
        return json.loads(self.meta.get("spec", "{}"))

    @property
    def body_info(self) -> dict[str, BodyInfo]:
        """Mass, inertia, radius and shape of each free body."""
        out = {}
        for b in json.loads(self.meta.get("bodies", "[]")):
            radius = b.get("radius")
            rest = b.get("rest_height_m", radius)  # older logs: spheres only
            shape = b.get("shape", "sphere" if radius is not None else "")
            geoms = tuple(b.get("geoms", ()))
            out[b["name"]] = BodyInfo(
                b["name"], b["mass"], tuple(b["inertia"]), radius, rest, shape, geoms
            )
        return out

    @property
    def surfaces(self) -> list[SurfaceInfo] | None:
        """The ground surfaces; None for logs written before they were recorded."""
        if "ground" not in self.meta:
            return None
        return [
            SurfaceInfo(s["name"], s["type"], float(s["level_m"]), bool(s["distance"]))
            for s in json.loads(self.meta["ground"])
        ]

    @property
    def static_potential_J(self) -> float:
        """MuJoCo's potential energy of the static bodies (0 in logs that do not say), J."""
        return float(self.meta.get("static_potential_J") or 0.0)

    @property
    def integrator(self) -> str:
        """MuJoCo's integrator ("Euler" for logs that do not say)."""
        spec = self.meta.get("integrator") or self.spec.get("options", {}).get("integrator")
        return spec or "Euler"

    @property
    def gravity(self) -> np.ndarray:
        """Gravity vector, m/s^2, (3,)."""
        return np.array(json.loads(self.meta.get("gravity", "[0, 0, -9.81]")), dtype=float)

    @property
    def plane_z(self) -> float | None:
        """Height of the ground plane in m, or None without a plane."""
        value = self.meta.get("plane_z", "")
        return float(value) if value else None

    @property
    def timestep_s(self) -> float:
        """The simulation timestep in s."""
        return float(self.meta["timestep_s"])

    @property
    def outcome(self) -> str:
        """completed, unstable, or incomplete (the log has no outcome record)."""
        return self.meta.get("outcome", "incomplete")


def find_logs(inputs: Sequence[str | Path]) -> list[Path]:
    """Expand files, folders (their *.mcap, recursively) and glob patterns, sorted, unique."""
    out: list[Path] = []
    for item in inputs:
        path = Path(item)
        if path.is_dir():
            out += sorted(path.rglob("*.mcap"))
        elif any(c in str(item) for c in "*?["):
            out += (
                sorted(Path().glob(str(item)))
                if not path.is_absolute()
                else sorted(Path(path.anchor).glob(str(path.relative_to(path.anchor))))
            )
        else:
            out.append(path)
    return list(dict.fromkeys(out))


def load_log(path: str | Path) -> RunLog:
    """Decode one log into frames.

    Raises:
        LogError: the file does not exist, is not MCAP, holds no impactlab channel, or its
            metadata values do not parse (damaged).
    """
    path = Path(path)
    try:
        raw = read_mcap(path, skip_topics=UNREAD_TOPICS)
    except FileNotFoundError:
        raise LogError(str(path), "file not found") from None
    except IsADirectoryError:
        raise LogError(str(path), "is a folder, not a log") from None
    except OSError as exc:
        raise LogError(str(path), f"cannot read: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise LogError(str(path), str(exc)) from None
    data = [c for c in raw.channels.values() if c.schema in DATA_SCHEMAS]
    if logformat.RUN_METADATA not in raw.metadata and not any(c.pieces for c in data):
        reason = raw.problems[0] if raw.problems else "no impactlab channels or metadata"
        raise LogError(str(path), f"not an impactlab log ({reason})")
    meta = dict(raw.metadata.get(logformat.RUN_METADATA, {}))
    problems = list(raw.problems)
    if not meta:
        problems.append("no impactlab.run metadata")
    if logformat.OUTCOME_METADATA in raw.metadata:
        meta.update(raw.metadata[logformat.OUTCOME_METADATA])
    else:
        problems.append("no outcome record: the log is incomplete")
    damaged = metadata_problem(meta)
    if damaged:
        raise LogError(str(path), f"damaged metadata: {damaged}")
    run_id = meta.get("run_id", path.stem)
    bodies: dict[str, pl.DataFrame] = {}
    contact_frames: list[pl.DataFrame] = []
    clearance_frames: list[pl.DataFrame] = []
    energy = empty_frame(ENERGY_FIELDS, run_id)
    events = pl.DataFrame(
        schema={"run_id": pl.String, "t_ns": pl.Int64, "level": pl.String, "message": pl.String}
    )
    for channel in raw.channels.values():
        schema, topic = channel.schema, channel.topic
        try:
            if schema == logformat.BODY_STATE_SCHEMA:
                t, values = decode_fixed(channel, messages.body_state(), body_state_values)
                name = channel.metadata.get("body") or topic.removeprefix("/bodies/").split("/")[0]
                bodies[name] = fixed_frame(run_id, t, values, BODY_FIELDS)
            elif schema == logformat.CONTACT_SCHEMA:
                contact_frames.append(decode_contacts(run_id, channel))
            elif schema == logformat.CLEARANCE_SCHEMA:
                clearance_frames.append(decode_clearance(run_id, channel))
            elif schema == logformat.ENERGY_SCHEMA:
                t, values = decode_fixed(channel, messages.energy(), energy_values)
                energy = fixed_frame(run_id, t, values, ENERGY_FIELDS)
            elif schema == "foxglove.Log" and topic == logformat.EVENTS_TOPIC:
                t, payloads = loose_payloads(channel)
                events = decode_events(run_id, t, payloads)
        except (DecodeError, ValueError) as exc:  # e.g. another tool's encoding of the schema
            raise LogError(str(path), f"{topic}: undecodable message ({exc})") from None
    contacts = (
        pl.concat(contact_frames).sort("t_ns", maintain_order=True)
        if contact_frames
        else empty_contacts(run_id)
    )
    return RunLog(
        path=path,
        run_id=run_id,
        meta=meta,
        bodies=dict(sorted(bodies.items())),
        contacts=contacts,
        energy=energy,
        events=events,
        partial=bool(problems),
        problems=problems,
        clearance=pl.concat(clearance_frames) if clearance_frames else empty_clearance(run_id),
    )
