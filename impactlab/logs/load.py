"""Read impactlab MCAP logs into polars frames. All decoding of log files happens here.

Each channel family becomes one frame with one row per message (per contact point for
contacts), with the run's id and the time (`t_ns`, integer ns; `t_s`, float s) as columns.
Records are gathered as arrays (`records.read_mcap`) and the fixed-layout messages decoded
as whole arrays (`codec.Template`), with the protobuf library as the fallback for any
other layout. A truncated or damaged file still yields every complete message before the
damage; such a run is marked `partial`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from google.protobuf.message import DecodeError

from impactlab.errors import LogError
from impactlab.logs import format as logformat
from impactlab.logs import messages
from impactlab.logs.bodies import BodyInfo as BodyInfo  # re-exported: readers import it here
from impactlab.logs.bodies import SurfaceInfo as SurfaceInfo
from impactlab.logs.contract import GeomContact, PairTarget, optional_keys
from impactlab.logs.decode import (
    Columns,
    body_state_values,
    decode_clearance,
    decode_contacts,
    decode_events,
    decode_fixed,
    decode_impacts,
    decode_pair_contacts,
    empty_clearance,
    empty_contacts,
    empty_frame,
    empty_impacts,
    energy_values,
    fixed_frame,
    loose_payloads,
)
from impactlab.logs.geoms import SCENE_METADATA
from impactlab.logs.messages import BODY_FIELDS, ENERGY_FIELDS, WORK_FIELDS
from impactlab.logs.metadata import ANALYSIS_KEYS, MetadataCheck, check_channels, check_metadata
from impactlab.logs.reader import read_mcap
from impactlab.proto import impactlab_pb2 as pb

UNREAD_TOPICS = frozenset({logformat.TF_TOPIC})  # poses for viewers; /bodies holds the same
DATA_SCHEMAS = frozenset(
    {
        logformat.BODY_STATE_SCHEMA,
        logformat.CONTACT_SCHEMA,
        logformat.CONTACTS_SCHEMA,
        logformat.ENERGY_SCHEMA,
        logformat.CLEARANCE_SCHEMA,
        logformat.IMPACT_SCHEMA,
        logformat.WORK_SCHEMA,
    }
)


@dataclass
class RunLog:
    """One decoded log.

    Attributes:
        path: the file.
        run_id: the run's id (file stem when the metadata lacks it).
        meta: the `impactlab.run` record merged with `impactlab.outcome`, as stored (strings).
        bodies: per body name, a frame (run_id, t_ns, t_s, x .. wz), world frame, SI units.
        contacts: one row per contact point (run_id, t_ns, t_s, geom1, geom2, body1, body2,
            point, x .. fz), see `schemas/impactlab.proto`.
        energy: MuJoCo's energy (run_id, t_ns, t_s, kinetic, potential, total), J.
        events: the log's text events (run_id, t_ns, level, message).
        partial: the file is damaged or incomplete, or its metadata; `problems` says how.
        clearance: each body's distance to each ground surface (run_id, t_ns, t_s, body,
            surface, clearance_m); empty in logs written before it was recorded.
        impacts: each contact episode of each pair of parties, found at every simulated
            step (`decode.IMPACT_SCHEMA`); empty in logs before format 3.
        work: the work of each kind of force so far (run_id, t_ns, t_s, *WORK_FIELDS), J;
            empty in logs before format 3.
        joint_energy: the energy MuJoCo counts in joints (run_id, t_ns, t_s, kinetic: rotor
            inertia, potential: springs, total), J; empty when the model has neither.
        checked: the metadata checked against its schema and the channels
            (`impactlab.logs.metadata`): typed values, and the problem of each bad key. The
            properties below read it, so a bad value reads as unknown.
        scene: the `impactlab.scene` record as stored (the geom table, `logs.geoms`; empty
            in logs written before it was recorded).
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
    checked: MetadataCheck = field(default_factory=lambda: MetadataCheck({}, {}))
    clearance: pl.DataFrame = field(default_factory=lambda: empty_clearance(""))
    joint_energy: pl.DataFrame = field(default_factory=lambda: empty_frame(ENERGY_FIELDS, ""))
    impacts: pl.DataFrame = field(default_factory=lambda: empty_impacts(""))
    work: pl.DataFrame = field(default_factory=lambda: empty_frame(WORK_FIELDS, ""))
    scene: dict[str, str] = field(default_factory=dict)

    @property
    def experiment(self) -> str:
        """The experiment's name ("" when unknown)."""
        experiment: str = self.checked.values.get("experiment", "")
        return experiment

    @property
    def sweep(self) -> dict[str, Any]:
        """This run's sweep point: {dotted path: value} ({} when unknown)."""
        sweep: dict[str, Any] = self.checked.values.get("sweep", {})
        return sweep

    @property
    def sweep_point(self) -> tuple[int, int]:
        """(index, size) of this run in its sweep grid; (0, 1) without a sweep or unknown."""
        values = self.checked.values
        return values.get("sweep_index", 0), values.get("sweep_size", 1)

    @property
    def spec(self) -> dict[str, Any]:
        """The resolved spec document the run was made from ({} when unknown)."""
        spec: dict[str, Any] = self.checked.values.get("spec", {})
        return spec

    @property
    def body_info(self) -> dict[str, BodyInfo]:
        """Mass, inertia, radius and shape of each free body ({} when unknown)."""
        out = {}
        for b in self.checked.values.get("bodies", []):
            radius = b.get("radius")
            rest = b.get("rest_height_m", radius)  # older logs: spheres only
            shape = b.get("shape", "sphere" if radius is not None else "")
            ix, iy, iz = (float(x) for x in b["inertia"])
            geoms, motion = tuple(b.get("geoms", ())), b.get("motion", "free")
            fields = (b["name"], float(b["mass"]), (ix, iy, iz), radius, rest, shape, geoms, motion)
            out[b["name"]] = BodyInfo(*fields)
        return out

    @property
    def surfaces(self) -> list[SurfaceInfo] | None:
        """The ground surfaces; None for logs written before they were recorded (or when
        the value is damaged: the analysis refuses such a run)."""
        ground = self.checked.values.get("ground")
        if ground is None:
            return None
        return [
            SurfaceInfo(s["name"], s["type"], float(s["level_m"]), bool(s["distance"]))
            for s in ground
        ]

    @property
    def static_potential_J(self) -> float:
        """MuJoCo's potential energy of the static bodies (0 in logs that do not say), J."""
        return float(self.checked.values.get("static_potential_J", 0.0))

    @property
    def integrator(self) -> str:
        """MuJoCo's integrator ("Euler" for logs that do not say)."""
        return self.checked.values.get("integrator") or "Euler"

    @property
    def half_step_s(self) -> float:
        """The integrator's half step, s (`physics.half_step_s`); LogError when unknown."""
        return float(self._known("half_step_s"))

    @property
    def contact_targets(self) -> tuple[PairTarget, ...]:
        """The pairs calibrated to a target e, with their speed ranges (() when none)."""
        return tuple(self.checked.values.get("contact_targets", ()))

    @property
    def geom_contact(self) -> GeomContact | None:
        """The contact parameters every geom shares (None: they differ, or unknown)."""
        return self.checked.values.get("geom_contact")

    @property
    def separation_m(self) -> float | None:
        """The separation stop rule, m: a collision was expected (None: no rule, unknown)."""
        return self.checked.values.get("separation_m")

    @property
    def gravity(self) -> np.ndarray:
        """Gravity vector, m/s^2, (3,).

        Raises:
            LogError: the log does not say (its metadata is missing or damaged).
        """
        return np.array(self._known("gravity"), dtype=float)

    @property
    def plane_z(self) -> float | None:
        """Height of the ground plane in m, or None without a plane (or when unknown)."""
        return self.checked.values.get("plane_z")

    @property
    def timestep_s(self) -> float:
        """The simulation timestep in s.

        Raises:
            LogError: the log does not say (its metadata is missing or damaged).
        """
        return float(self._known("timestep_s"))

    @property
    def log_every(self) -> int:
        """Simulation steps between two logged rows (1 when the log does not say)."""
        return int(self.checked.values.get("log_every", 1))

    @property
    def outcome(self) -> str:
        """completed, unstable, or incomplete (no outcome record, or an unknown outcome)."""
        outcome: str = self.checked.values.get("outcome", "incomplete")
        return outcome

    @property
    def warnings(self) -> list[str]:
        """The run's warnings, as recorded ([] when unknown)."""
        warnings: list[str] = self.checked.values.get("warnings", [])
        return warnings

    def unanalyzable(self) -> str | None:
        """Why the analysis cannot trust this run's metadata, or None.

        The masses, sizes, gravity, ground, timestep, logging stride and integrator must be
        known and agree with the channels: every energy, height and restitution depends on
        them (keys older logs lack, `contract.optional_keys`, may be missing).
        """
        optional = optional_keys(self.checked.values.get("log_format_version"))
        missing = [
            k
            for k in ANALYSIS_KEYS
            if k not in self.meta and k not in self.checked.problems and k not in optional
        ]
        if missing and not self.meta:
            return "no impactlab.run metadata: cannot analyze"
        parts = [f"{k}: {p}" for k, p in self.checked.blocking().items()]
        parts += [f"{k}: missing" for k in missing]
        return f"damaged metadata: {'; '.join(parts)}: cannot analyze" if parts else None

    def __repr__(self) -> str:
        from impactlab.logs.view import log_repr

        return log_repr(self)

    def _repr_html_(self) -> str:
        """A small table for notebooks (`impactlab.logs.view`)."""
        from impactlab.logs.view import log_html

        return log_html(self)

    def _known(self, key: str) -> Any:
        if key in self.checked.values:
            return self.checked.values[key]
        problem = self.checked.problems.get(key, "missing")
        raise LogError(str(self.path), f"damaged metadata: {key}: {problem}")


def load_log(path: str | Path) -> RunLog:
    """Decode one log into frames.

    Damage and bad metadata do not raise: whatever is readable is returned, marked partial,
    with one problem per damage and per bad metadata key (`RunLog.problems`).

    Raises:
        LogError: the file does not exist, is not a regular file, is too large, is not MCAP,
            or holds no impactlab channel or metadata.
    """
    path = Path(path)
    try:
        raw = read_mcap(path, skip_topics=UNREAD_TOPICS, reuse_memory=True)
    except FileNotFoundError:
        raise LogError(str(path), "file not found") from None
    except IsADirectoryError:
        raise LogError(str(path), "is a folder, not a log") from None
    except OSError as exc:
        raise LogError(str(path), f"cannot read: {exc.strerror or exc}") from None
    except ValueError as exc:  # not a regular file, too large, not MCAP
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
    checked = check_metadata(raw.metadata)
    run_id = checked.values.get("run_id", path.stem)
    bodies: dict[str, pl.DataFrame] = {}
    contact_frames: list[pl.DataFrame] = []
    clearance_frames: list[pl.DataFrame] = []
    impacts: pl.DataFrame | None = None
    work: pl.DataFrame | None = None
    energy: pl.DataFrame | None = None
    columns = Columns()  # the columns the frames repeat, built once
    joint_energy: pl.DataFrame | None = None
    events: pl.DataFrame | None = None
    for channel in raw.channels.values():
        schema, topic = channel.schema, channel.topic
        try:
            if schema == logformat.BODY_STATE_SCHEMA:
                t, values = decode_fixed(channel, messages.body_state(), body_state_values)
                name = channel.metadata.get("body") or topic.removeprefix("/bodies/").split("/")[0]
                bodies[name] = fixed_frame(run_id, t, values, BODY_FIELDS, columns)
            elif schema == logformat.CONTACTS_SCHEMA:
                contact_frames.append(decode_contacts(run_id, channel))
            elif schema == logformat.CONTACT_SCHEMA:
                contact_frames.append(decode_pair_contacts(run_id, channel))
            elif schema == logformat.CLEARANCE_SCHEMA:
                clearance_frames.append(decode_clearance(run_id, channel, columns))
            elif schema == logformat.IMPACT_SCHEMA:
                impacts = decode_impacts(run_id, loose_payloads(channel)[1])
            elif schema == logformat.WORK_SCHEMA:
                t, values = decode_fixed(channel, messages.work(), _work_values)
                work = fixed_frame(run_id, t, values, WORK_FIELDS, columns)
            elif schema == logformat.ENERGY_SCHEMA:
                t, values = decode_fixed(channel, messages.energy(), energy_values)
                if topic == logformat.JOINT_ENERGY_TOPIC:
                    joint_energy = fixed_frame(run_id, t, values, ENERGY_FIELDS, columns)
                else:
                    energy = fixed_frame(run_id, t, values, ENERGY_FIELDS, columns)
            elif schema == "foxglove.Log" and topic == logformat.EVENTS_TOPIC:
                t, payloads = loose_payloads(channel)
                events = decode_events(run_id, t, payloads)
        except (DecodeError, ValueError) as exc:  # e.g. another tool's encoding of the schema
            raise LogError(str(path), f"{topic}: undecodable message ({exc})") from None
    if len(contact_frames) == 1 and contact_frames[0]["t_ns"].is_sorted():
        contacts = contact_frames[0]  # as sorting would leave it
    elif contact_frames:
        contacts = pl.concat(contact_frames).sort("t_ns", maintain_order=True)
    else:
        contacts = empty_contacts(run_id)
    times = {name: f["t_ns"].to_numpy() for name, f in bodies.items()}
    check_channels(checked, times, complete=not raw.problems)
    problems += checked.lines()
    return RunLog(
        path=path,
        run_id=run_id,
        meta=meta,
        bodies=dict(sorted(bodies.items())),
        contacts=contacts,
        energy=empty_frame(ENERGY_FIELDS, run_id) if energy is None else energy,
        events=decode_events(run_id, np.empty(0, np.int64), []) if events is None else events,
        partial=bool(problems),
        problems=problems,
        checked=checked,
        clearance=pl.concat(clearance_frames) if clearance_frames else empty_clearance(run_id),
        joint_energy=empty_frame(ENERGY_FIELDS, run_id) if joint_energy is None else joint_energy,
        impacts=empty_impacts(run_id) if impacts is None else impacts,
        work=empty_frame(WORK_FIELDS, run_id) if work is None else work,
        scene=dict(raw.metadata.get(SCENE_METADATA, {})),
    )


def _work_values(data: bytes) -> list[float]:
    """One `impactlab.Work` payload's values, by the protobuf library."""
    w = pb.Work.FromString(data)
    return [getattr(w, f) for f in WORK_FIELDS]
