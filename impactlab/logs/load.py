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
from collections import defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from google.protobuf.message import DecodeError

from impactlab.errors import LogError
from impactlab.logs import format as logformat
from impactlab.logs import messages
from impactlab.logs.codec import Template
from impactlab.logs.messages import BODY_FIELDS, ENERGY_FIELDS, POINT_FIELDS
from impactlab.logs.reader import ChannelData, read_mcap
from impactlab.proto import impactlab_pb2 as pb

UNREAD_TOPICS = frozenset({logformat.TF_TOPIC})  # poses for viewers; /bodies holds the same
DATA_SCHEMAS = frozenset(
    {logformat.BODY_STATE_SCHEMA, logformat.CONTACT_SCHEMA, logformat.ENERGY_SCHEMA}
)


@dataclass(frozen=True)
class BodyInfo:
    """A free body as the log's metadata describes it (kg, kg m^2 principal, m)."""

    name: str
    mass: float
    inertia: tuple[float, float, float]
    radius: float | None


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
        """Mass, inertia and radius of each free body."""
        return {
            b["name"]: BodyInfo(b["name"], b["mass"], tuple(b["inertia"]), b.get("radius"))
            for b in json.loads(self.meta.get("bodies", "[]"))
        }

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
    energy = _empty(ENERGY_FIELDS, run_id)
    events = pl.DataFrame(
        schema={"run_id": pl.String, "t_ns": pl.Int64, "level": pl.String, "message": pl.String}
    )
    for channel in raw.channels.values():
        schema, topic = channel.schema, channel.topic
        try:
            if schema == logformat.BODY_STATE_SCHEMA:
                t, values = decode_fixed(channel, messages.body_state(), _body_state_values)
                name = channel.metadata.get("body") or topic.removeprefix("/bodies/").split("/")[0]
                bodies[name] = _frame(run_id, t, values, BODY_FIELDS)
            elif schema == logformat.CONTACT_SCHEMA:
                contact_frames.append(decode_contacts(run_id, channel))
            elif schema == logformat.ENERGY_SCHEMA:
                t, values = decode_fixed(channel, messages.energy(), _energy_values)
                energy = _frame(run_id, t, values, ENERGY_FIELDS)
            elif schema == "foxglove.Log" and topic == logformat.EVENTS_TOPIC:
                t, payloads = _loose(channel)
                events = decode_events(run_id, t, payloads)
        except (DecodeError, ValueError) as exc:  # e.g. another tool's encoding of the schema
            raise LogError(str(path), f"{topic}: undecodable message ({exc})") from None
    contacts = (
        pl.concat(contact_frames).sort("t_ns", maintain_order=True)
        if contact_frames
        else _empty_contacts(run_id)
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
    )


def metadata_problem(meta: dict[str, str]) -> str | None:
    """What is wrong with the values of the run and outcome metadata, or None.

    Metadata records carry no CRC: a damaged byte can leave a value that does not parse.
    Keys that are absent are not checked (the callers handle them).
    """

    def number(text: str) -> bool:
        try:
            return np.isfinite(float(text))
        except ValueError:
            return False

    def integer(text: str) -> bool:
        return text.isdigit()

    def vector(value: Any) -> bool:
        return isinstance(value, list) and len(value) == 3 and all(_real(v) for v in value)

    def body(value: Any) -> bool:
        return (
            isinstance(value, dict)
            and isinstance(value.get("name"), str)
            and _real(value.get("mass"))
            and vector(value.get("inertia"))
            and (value.get("radius") is None or _real(value.get("radius")))
        )

    checks: dict[str, Callable[[str], bool]] = {
        "timestep_s": lambda t: number(t) and float(t) > 0,
        "log_every": lambda t: integer(t) and int(t) > 0,
        "plane_z": lambda t: t == "" or number(t),
        "steps": integer,
    }
    json_checks: dict[str, Callable[[Any], bool]] = {
        "spec": lambda v: isinstance(v, dict),
        "sweep": lambda v: isinstance(v, dict),
        "gravity": vector,
        "bodies": lambda v: isinstance(v, list) and all(body(b) for b in v),
        "warnings": lambda v: isinstance(v, list) and all(isinstance(w, str) for w in v),
    }
    for key, ok in checks.items():
        if key in meta and not ok(meta[key]):
            return f"{key} = {meta[key][:40]!r} is not valid"
    for key, ok in json_checks.items():
        if key not in meta:
            continue
        try:
            valid = ok(json.loads(meta[key]))
        except ValueError:
            valid = False
        if not valid:
            return f"{key} is not valid JSON of the expected shape"
    return None


def _real(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def decode_fixed(
    channel: ChannelData, layout: Template, fallback: Callable[[bytes], list[float]]
) -> tuple[np.ndarray, np.ndarray]:
    """A channel's times (n,) and values (n, k), sorted by time.

    Pieces in the template's layout are decoded as arrays; anything else goes through the
    protobuf library (`fallback` turns one payload into its values).
    """
    times, values = [], []
    for t, data in channel.pieces:
        decoded = layout.decode(data) if isinstance(data, np.ndarray) else None
        if decoded is None:
            rows = data if isinstance(data, list) else [bytes(r) for r in data]
            decoded = np.asarray([fallback(r) for r in rows], dtype=np.float64)
        times.append(t)
        values.append(decoded.reshape(len(t), -1))
    if not times:
        return np.empty(0, np.int64), np.empty((0, len(layout.slots)))
    t_all, v_all = np.concatenate(times), np.concatenate(values)
    if (np.diff(t_all) >= 0).all():
        return t_all, v_all
    order = np.argsort(t_all, kind="stable")
    return t_all[order], v_all[order]


def _body_state_values(data: bytes) -> list[float]:
    m = pb.BodyState.FromString(data)
    return [getattr(m, f) for f in BODY_FIELDS]


def _energy_values(data: bytes) -> list[float]:
    m = pb.Energy.FromString(data)
    return [m.kinetic, m.potential, m.total]


def _loose(channel: ChannelData) -> tuple[np.ndarray, list[bytes]]:
    """A channel's messages as (times, payload bytes), sorted by time."""
    times, payloads = [], []
    for t, data in channel.pieces:
        times += t.tolist()
        payloads += data if isinstance(data, list) else [bytes(r) for r in data]
    order = np.argsort(np.asarray(times, dtype=np.int64), kind="stable")
    return np.asarray(times, dtype=np.int64)[order], [payloads[i] for i in order]


def decode_contacts(run_id: str, channel: ChannelData) -> pl.DataFrame:
    """A Contact channel -> one row per contact point."""
    names = {k: channel.metadata.get(k, "") for k in ("geom1", "geom2", "body1", "body2")}
    per_point = len(POINT_FIELDS)
    frames = []
    for t, data in channel.pieces:
        values = None
        if isinstance(data, np.ndarray) and all(names.values()):
            # a payload of k points is one point's bytes longer than one of k - 1
            one = messages.contact(*names.values(), 1).size
            two = messages.contact(*names.values(), 2).size
            k, rest = divmod(data.shape[1] - one, two - one)
            if rest == 0 and k >= 0:
                values = messages.contact(*names.values(), k + 1).decode(data)
        if values is not None:
            points = values.reshape(len(t), -1, per_point)
            frames.append(_contact_frame(run_id, t, names, points))
        else:
            rows = data if isinstance(data, list) else [bytes(r) for r in data]
            frames.append(_contact_frame_slow(run_id, t, rows))
    if not frames:
        return _empty_contacts(run_id)
    return frames[0] if len(frames) == 1 else pl.concat(frames).sort(["t_ns", "point"])


def _contact_frame(run_id: str, t: np.ndarray, names: dict[str, str], points: np.ndarray):
    n, k, _ = points.shape
    rows = n * k
    t_rep = np.repeat(t, k)
    columns: dict[str, Any] = {
        "run_id": _constant(run_id, rows),
        "t_ns": pl.Series(t_rep, dtype=pl.Int64),
        "t_s": pl.Series(t_rep / 1e9, dtype=pl.Float64),
    }
    columns |= {key: _constant(v, rows) for key, v in names.items()}
    columns["point"] = pl.Series(np.tile(np.arange(k, dtype=np.int32), n), dtype=pl.Int32)
    flat = points.reshape(rows, -1)
    columns |= {f: flat[:, i] for i, f in enumerate(POINT_FIELDS)}
    return pl.DataFrame(columns)


def _contact_frame_slow(run_id: str, t_ns: np.ndarray, payloads: Sequence[bytes]):
    cols: dict[str, list[Any]] = defaultdict(list)
    for t, data in zip(t_ns.tolist(), payloads, strict=True):
        m = pb.Contact.FromString(data)
        for i, p in enumerate(m.points):
            cols["t_ns"].append(t)
            cols["geom1"].append(m.geom1)
            cols["geom2"].append(m.geom2)
            cols["body1"].append(m.body1)
            cols["body2"].append(m.body2)
            cols["point"].append(i)
            for f in POINT_FIELDS:
                cols[f].append(getattr(p, f))
    if not cols:
        return _empty_contacts(run_id)
    frame = pl.DataFrame(dict(cols)).with_columns(
        pl.col("t_ns").cast(pl.Int64), pl.col("point").cast(pl.Int32)
    )
    return frame.select(
        pl.lit(run_id).alias("run_id"),
        "t_ns",
        pl.Series("t_s", frame["t_ns"].to_numpy() / 1e9),  # as the fast path (numpy division)
        *frame.columns[1:],
    )


def decode_events(run_id: str, t_ns: np.ndarray, payloads: Sequence[bytes]) -> pl.DataFrame:
    """foxglove.Log payloads -> (run_id, t_ns, level, message)."""
    from foxglove_schemas_protobuf.Log_pb2 import Log

    levels, messages = [], []
    for data in payloads:
        m = Log.FromString(data)
        levels.append(Log.Level.Name(m.level))
        messages.append(m.message)
    return pl.DataFrame(
        {"run_id": [run_id] * len(levels), "t_ns": t_ns, "level": levels, "message": messages},
        schema={"run_id": pl.String, "t_ns": pl.Int64, "level": pl.String, "message": pl.String},
    )


def _constant(value: str, n: int) -> pl.Series:
    """A string column of one value (eager: no query plan per column)."""
    return pl.Series([value], dtype=pl.String).new_from_index(0, n)


def _frame(run_id: str, t_ns: np.ndarray, values: np.ndarray, names: Sequence[str]):
    columns: dict[str, Any] = {
        "run_id": _constant(run_id, len(t_ns)),
        "t_ns": pl.Series(t_ns, dtype=pl.Int64),
        "t_s": pl.Series(t_ns / 1e9, dtype=pl.Float64),
    }
    columns |= {name: values[:, i] for i, name in enumerate(names)}
    return pl.DataFrame(columns)


def _empty(names: Sequence[str], run_id: str) -> pl.DataFrame:
    return _frame(run_id, np.empty(0, np.int64), np.empty((0, len(names))), names)


def _empty_contacts(run_id: str) -> pl.DataFrame:
    schema: dict[str, Any] = {"run_id": pl.String, "t_ns": pl.Int64, "t_s": pl.Float64}
    schema |= {k: pl.String for k in ("geom1", "geom2", "body1", "body2")}
    schema["point"] = pl.Int32
    schema |= {f: pl.Float64 for f in POINT_FIELDS}
    return pl.DataFrame(schema=schema)
