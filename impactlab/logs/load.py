"""Read impactlab logs into polars frames: one frame per channel family, with their metadata."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from google.protobuf.message import DecodeError

from impactlab.errors import LogError
from impactlab.logs import decode, messages
from impactlab.logs import format as logformat
from impactlab.logs.checks import MetadataCheck, check_channels, check_metadata, optional_keys
from impactlab.logs.inputs import log_errors
from impactlab.logs.messages import BODY_FIELDS, ENERGY_FIELDS, WORK_FIELDS
from impactlab.logs.metadata import ANALYSIS_KEYS, Body, GeomContact, PairTarget, Surface
from impactlab.logs.reader import read_mcap
from impactlab.proto import impactlab_pb2 as pb
from impactlab.show import count, html_table, plain

BodyInfo = Body  # the names readers know them by
SurfaceInfo = Surface
UNREAD_TOPICS = frozenset({logformat.TF_TOPIC})  # poses for viewers; /bodies holds the same
ONE_PER_STEP = (  # schemas of channels with at most one message per logged step
    logformat.BODY_STATE_SCHEMA,
    logformat.CLEARANCE_SCHEMA,
    logformat.CONTACTS_SCHEMA,
    logformat.CONTACT_SCHEMA,
    logformat.ENERGY_SCHEMA,
    logformat.WORK_SCHEMA,
)
DATA_SCHEMAS = frozenset({*ONE_PER_STEP, logformat.IMPACT_SCHEMA})  # impactlab channels


def _empty(names: tuple[str, ...]) -> pl.DataFrame:
    return decode.frame("", np.empty(0, np.int64), {n: np.empty(0) for n in names})


@dataclass
class RunLog:
    """One decoded log: a frame per channel family (run_id, t_ns, t_s, then its fields, SI
    units; `bodies` one per body; `contacts` a row per point; `clearance` a row per step and
    surface; `impacts` a row per contact episode, `decode.IMPACT_SCHEMA`), `meta` (the run
    and outcome records as stored), `checked` (their typed values and each bad key's
    problem: the properties read it, a bad value is unknown), `scene` (the geom table, as
    stored), and whether it is `partial` (damaged, incomplete, or bad metadata: `problems`)."""

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
    clearance: pl.DataFrame = field(
        default_factory=lambda: pl.DataFrame(schema=decode.CLEARANCE_SCHEMA)
    )
    joint_energy: pl.DataFrame = field(default_factory=lambda: _empty(ENERGY_FIELDS))
    impacts: pl.DataFrame = field(default_factory=lambda: pl.DataFrame(schema=decode.IMPACT_SCHEMA))
    work: pl.DataFrame = field(default_factory=lambda: _empty(WORK_FIELDS))
    scene: dict[str, str] = field(default_factory=dict)

    def _value(self, key: str, default: Any = None) -> Any:
        return self.checked.values.get(key, default)

    @property
    def experiment(self) -> str:
        """The experiment's name ("" when unknown)."""
        return str(self._value("experiment", ""))

    @property
    def sweep(self) -> dict[str, Any]:
        """This run's sweep point: {dotted path: value} ({} when unknown)."""
        return dict(self._value("sweep", {}))

    @property
    def sweep_point(self) -> tuple[int, int]:
        """(index, size) of this run in its sweep grid; (0, 1) without a sweep or unknown."""
        return self._value("sweep_index", 0), self._value("sweep_size", 1)

    @property
    def spec(self) -> dict[str, Any]:
        """The resolved spec document the run was made from ({} when unknown)."""
        return dict(self._value("spec", {}))

    @property
    def body_info(self) -> dict[str, Body]:
        """Mass, inertia, radius and shape of each body ({} when unknown)."""
        return {b.name: b for b in self._value("bodies", ())}

    @property
    def surfaces(self) -> list[Surface] | None:
        """The ground surfaces; None when the log does not say (the analysis refuses it)."""
        ground = self._value("ground")
        return None if ground is None else list(ground)

    @property
    def static_potential_J(self) -> float:
        """MuJoCo's potential energy of the static bodies (0 in logs that do not say), J."""
        return float(self._value("static_potential_J", 0.0))

    @property
    def integrator(self) -> str:
        """MuJoCo's integrator ("Euler" for logs that do not say)."""
        return str(self._value("integrator") or "Euler")

    @property
    def half_step_s(self) -> float:
        """The integrator's half step, s (`physics.half_step_s`); LogError when unknown."""
        return float(self._known("half_step_s"))

    @property
    def contact_targets(self) -> tuple[PairTarget, ...]:
        """The pairs calibrated to a target e, with their speed ranges (() when none)."""
        return tuple(self._value("contact_targets", ()))

    @property
    def geom_contact(self) -> GeomContact | None:
        """The contact parameters every geom shares (None: they differ, or unknown)."""
        return self._value("geom_contact")  # type: ignore[no-any-return]

    @property
    def separation_m(self) -> float | None:
        """The separation stop rule, m: a collision was expected (None: no rule, unknown)."""
        return self._value("separation_m")  # type: ignore[no-any-return]

    @property
    def gravity(self) -> np.ndarray:
        """Gravity vector, m/s^2, (3,); LogError when the log does not say."""
        return np.array(self._known("gravity"), dtype=float)

    @property
    def plane_z(self) -> float | None:
        """Height of the ground plane in m, or None without a plane (or when unknown)."""
        return self._value("plane_z")  # type: ignore[no-any-return]

    @property
    def timestep_s(self) -> float:
        """The simulation timestep in s; LogError when the log does not say."""
        return float(self._known("timestep_s"))

    @property
    def log_every(self) -> int:
        """Simulation steps between two logged rows (1 when the log does not say)."""
        return int(self._value("log_every", 1))

    @property
    def outcome(self) -> str:
        """completed, unstable, or incomplete (no outcome record, or an unknown outcome)."""
        return str(self._value("outcome", "incomplete"))

    @property
    def warnings(self) -> list[str]:
        """The run's warnings, as recorded ([] when unknown)."""
        return list(self._value("warnings", ()))

    def unanalyzable(self) -> str | None:
        """Why the analysis cannot trust this run's metadata (`ANALYSIS_KEYS`), or None."""
        optional = optional_keys(self._value("log_format_version"))
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

    def _known(self, key: str) -> Any:
        if key in self.checked.values:
            return self.checked.values[key]
        problem = self.checked.problems.get(key, "missing")
        raise LogError(str(self.path), f"damaged metadata: {key}: {problem}")

    def __repr__(self) -> str:
        """`<RunLog drop-1: drop, completed, 1.39 s, 1 body, 13,903 states, 26 contact points>`."""
        parts = [plain(self.experiment) or "unknown experiment", plain(self.outcome)]
        ends = [float(f["t_s"][-1]) for f in self.bodies.values() if f.height]
        parts += [f"{max(ends):.4g} s"] if ends else []
        parts += [
            count(len(self.bodies), "body", "bodies"),
            count(sum(f.height for f in self.bodies.values()), "state"),
            count(self.contacts.height, "contact point"),
        ]
        parts += [f"partial: {count(len(self.problems), 'problem')}"] if self.partial else []
        return f"<RunLog {plain(self.run_id)}: {', '.join(parts)}>"

    def _repr_html_(self) -> str:
        """The run, its outcome, and one row per channel with its rows and time span."""
        channels = [(f"body {n}", f) for n, f in self.bodies.items()]
        channels += [("contact points", self.contacts), ("energy", self.energy)]
        rows: list[list[object]] = [
            [
                label,
                f.height,
                f["t_s"].min() if f.height else None,
                f["t_s"].max() if f.height else None,
            ]
            for label, f in channels
        ]
        rows.append(["events", self.events.height, None, None])
        reason = self.meta.get("reason", "")
        caption = f"{self.run_id} ({self.experiment or 'unknown experiment'}): {self.outcome}"
        caption += (f" ({reason})" if reason else "") + f"; {self.path}"
        table = html_table(["channel", "rows", "first t (s)", "last t (s)"], rows, caption=caption)
        if self.problems:
            table += html_table(
                ["problems (partial log)"], [[p] for p in self.problems], unit="problems"
            )
        return table


def load_log(path: str | Path) -> RunLog:
    """Decode one log into frames: whatever is readable, marked partial with one problem per
    damage and bad metadata key. LogError when the file does not exist, is not a regular
    file, is too large, is not MCAP, or holds no impactlab channel or metadata."""
    path = Path(path)
    with log_errors(path):
        raw = read_mcap(path, skip_topics=UNREAD_TOPICS)
    data = [c for c in raw.channels.values() if c.schema in DATA_SCHEMAS]
    if logformat.RUN_METADATA not in raw.metadata and not any(c.pieces for c in data):
        reason = raw.problems[0] if raw.problems else "no impactlab channels or metadata"
        raise LogError(str(path), f"not an impactlab log ({reason})")
    meta = dict(raw.metadata.get(logformat.RUN_METADATA, {}))
    problems = list(raw.problems) + ([] if meta else ["no impactlab.run metadata"])
    if logformat.OUTCOME_METADATA in raw.metadata:
        meta.update(raw.metadata[logformat.OUTCOME_METADATA])
    else:
        problems.append("no outcome record: the log is incomplete")
    checked = check_metadata(raw.metadata, raw.conflicts)
    run_id = checked.values.get("run_id", path.stem)
    bodies: dict[str, pl.DataFrame] = {}
    contacts: list[pl.DataFrame] = []
    clearance: list[pl.DataFrame] = []
    frames: dict[str, pl.DataFrame] = {}  # energy, joint_energy, work, impacts, events
    for channel in raw.channels.values():
        schema, topic = channel.schema, channel.topic
        if schema in ONE_PER_STEP and (repeated := decode.drop_repeated_times(channel)):
            problems.append(
                f"damaged: {topic}: {repeated:,} messages at a time the channel already has "
                "a message at (the first kept)"
            )
        try:
            if schema == logformat.BODY_STATE_SCHEMA:
                name = channel.metadata.get("body") or topic.removeprefix("/bodies/").split("/")[0]
                bodies[name] = decode.values_frame(
                    run_id, channel, messages.body_state(), BODY_FIELDS, pb.BodyState
                )
            elif schema in (logformat.CONTACTS_SCHEMA, logformat.CONTACT_SCHEMA):
                contacts.append(decode.contacts(run_id, channel))
            elif schema == logformat.CLEARANCE_SCHEMA:
                clearance.append(decode.clearance(run_id, channel))
            elif schema == logformat.IMPACT_SCHEMA:
                frames["impacts"] = decode.impacts(run_id, channel)
            elif schema == logformat.WORK_SCHEMA:
                frames["work"] = decode.values_frame(
                    run_id, channel, messages.work(), WORK_FIELDS, pb.Work
                )
            elif schema == logformat.ENERGY_SCHEMA:
                key = "joint_energy" if topic == logformat.JOINT_ENERGY_TOPIC else "energy"
                frames[key] = decode.values_frame(
                    run_id, channel, messages.energy(), ENERGY_FIELDS, pb.Energy
                )
            elif schema == "foxglove.Log" and topic == logformat.EVENTS_TOPIC:
                frames["events"] = decode.events(run_id, channel)
        except (DecodeError, ValueError) as exc:  # e.g. another tool's encoding of the schema
            raise LogError(str(path), f"{topic}: undecodable message ({exc})") from None
    if len(contacts) > 1 or (contacts and not contacts[0]["t_ns"].is_sorted()):
        contacts = [pl.concat(contacts).sort("t_ns", maintain_order=True)]
    times = {name: frame["t_ns"].to_numpy() for name, frame in bodies.items()}
    check_channels(checked, times, complete=not raw.problems)
    problems += checked.lines()
    return RunLog(
        path=path,
        run_id=run_id,
        meta=meta,
        bodies=dict(sorted(bodies.items())),
        contacts=contacts[0] if contacts else pl.DataFrame(schema=decode.CONTACT_SCHEMA),
        energy=frames.pop("energy") if "energy" in frames else _empty(ENERGY_FIELDS),
        events=frames.pop("events") if "events" in frames else decode.events(run_id, None),
        partial=bool(problems),
        problems=problems,
        checked=checked,
        clearance=pl.concat(clearance)
        if clearance
        else pl.DataFrame(schema=decode.CLEARANCE_SCHEMA),
        scene=dict(raw.metadata.get(logformat.SCENE_METADATA, {})),
        **frames,
    )
