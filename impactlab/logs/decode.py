"""A log's channels as polars frames: fixed layouts decoded as arrays, the rest by protobuf."""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import polars as pl
from foxglove_schemas_protobuf.Log_pb2 import Log

from impactlab.logs import format as logformat
from impactlab.logs import messages
from impactlab.logs.messages import BODY_FIELDS, POINT_FIELDS, POINT_RECORD, Template
from impactlab.logs.metadata import Text, adapter
from impactlab.logs.reader import ChannelData
from impactlab.proto import impactlab_pb2 as pb

TIME: dict[str, Any] = {"run_id": pl.String, "t_ns": pl.Int64, "t_s": pl.Float64}
CONTACT_SCHEMA: dict[str, Any] = {
    **TIME,
    **dict.fromkeys(("geom1", "geom2", "body1", "body2"), pl.String),
    "point": pl.Int32,
    **dict.fromkeys(POINT_FIELDS, pl.Float64),
}
CLEARANCE_SCHEMA: dict[str, Any] = {
    **TIME,
    "body": pl.String,
    "surface": pl.String,
    "clearance_m": pl.Float64,
}
IMPACT_NUMBERS = (
    "v_in_mps v_out_mps work_compression_J work_restitution_J work_friction_J peak_force_N "
    "impulse_Ns max_penetration_m"
)
IMPACT_SCHEMA: dict[str, Any] = {
    "run_id": pl.String,
    **dict.fromkeys(("side1", "kind1", "side2", "kind2", "geom1", "geom2"), pl.String),
    "onset_ns": pl.Int64,
    "release_ns": pl.Int64,
    **dict.fromkeys(IMPACT_NUMBERS.split(), pl.Float64),
    "steps": pl.Int64,
    "open": pl.Boolean,
    **{f"{v}{c}_{w}": pl.Float64 for w in ("in", "out") for v in ("p", "n") for c in "xyz"},
    **{f"s{k}_{w}_{f}": pl.Float64 for w in ("in", "out") for k in (1, 2) for f in BODY_FIELDS},
}
"""The `/impacts` frame: one row per contact episode (`impactlab.Impact`): point and normal at
the first and last step (`px_in` .. `nz_out`), each side's state at the first step in contact
and the first after (`s1_in_x` .. `s2_out_wz`; null for a side that is not a rigid body)."""


IMPACT_SCALARS = pb.Impact.DESCRIPTOR.fields[:18]
"""`impactlab.Impact`'s fields side1 .. open: `IMPACT_SCHEMA`'s columns after run_id, in order."""


def frame(run_id: str, t_ns: np.ndarray, columns: dict[str, Any]) -> pl.DataFrame:
    """(run_id, t_ns, t_s, *columns) of times (n,) int64 ns and columns of n values."""
    return pl.DataFrame(
        [
            pl.Series("run_id", [run_id], pl.String).new_from_index(0, len(t_ns)),
            pl.Series("t_ns", t_ns, pl.Int64),
            pl.Series("t_s", t_ns / 1e9, pl.Float64),
            *(pl.Series(name, values) for name, values in columns.items()),
        ]
    )


def drop_repeated_times(channel: ChannelData) -> int:
    """Keep a channel's first message at each time (in file order), for channels with one
    message per step; the number of messages dropped."""
    t = np.concatenate([np.empty(0, np.int64), *(t for t, _ in channel.pieces)])
    order = np.argsort(t, kind="stable")
    repeat = np.zeros(t.size, bool)
    repeat[order[1:]] = t[order[1:]] == t[order[:-1]]
    if not repeat.any():
        return 0
    pieces, at = [], 0
    for times, data in channel.pieces:
        keep = ~repeat[at : at + len(times)]
        at += len(times)
        kept = data[keep] if isinstance(data, np.ndarray) else list(itertools.compress(data, keep))
        pieces.append((times[keep], kept))
    channel.pieces = pieces
    return int(repeat.sum())


def payloads(channel: ChannelData) -> tuple[np.ndarray, list[bytes]]:
    """A channel's messages as (times, payload bytes), sorted by time."""
    times = [np.empty(0, np.int64), *(t for t, _ in channel.pieces)]
    data: list[bytes] = []
    for _, piece in channel.pieces:
        data += piece if isinstance(piece, list) else [row.tobytes() for row in piece]
    t = np.concatenate(times)
    if (np.diff(t) >= 0).all():
        return t, data
    order = np.argsort(t, kind="stable")
    return t[order], [data[i] for i in order.tolist()]


def fixed(
    channel: ChannelData, layout: Template, library: Callable[[bytes], Sequence[float]]
) -> tuple[np.ndarray, np.ndarray]:
    """A channel's times (n,) and values (n, k), sorted by time: pieces in the layout decoded
    as arrays, any other payload by the protobuf library (`library`)."""
    times, values = [np.empty(0, np.int64)], [np.empty((0, layout.slots.size))]
    for t, data in channel.pieces:
        decoded = layout.decode(data) if isinstance(data, np.ndarray) else None
        if decoded is None:
            decoded = np.array([library(bytes(p)) for p in data], np.float64).reshape(len(t), -1)
        times.append(t)
        values.append(decoded)
    t, v = np.concatenate(times), np.concatenate(values) if len(values) > 2 else values[-1]
    if (np.diff(t) >= 0).all():
        return t, v
    order = np.argsort(t, kind="stable")
    return t[order], v[order]


def values_frame(
    run_id: str, channel: ChannelData, layout: Template, names: Sequence[str], kind: Any
) -> pl.DataFrame:
    """A channel of one fixed-layout message type (`kind`, fields `names`) as a frame."""
    t, v = fixed(channel, layout, lambda d: [getattr(kind.FromString(d), f) for f in names])
    return frame(run_id, t, {name: v[:, j] for j, name in enumerate(names)})


def clearance(run_id: str, channel: ChannelData) -> pl.DataFrame:
    """A Clearance channel -> one row per logged step and surface (the channel's metadata
    names the body and, JSON, the surfaces in value order).

    Raises:
        ValueError: the metadata does not name them, or a message holds another count.
    """
    body, surfaces = channel.metadata.get("body", ""), _names(channel.metadata.get("surfaces"))
    if not body or surfaces is None:
        raise ValueError("the channel's metadata does not name its body and surfaces")
    k = len(surfaces)

    def library(data: bytes) -> list[float]:
        values = list(pb.Clearance.FromString(data).distance)
        if len(values) != k:
            raise ValueError(f"{len(values)} distances for {k} surfaces")
        return values

    t, v = fixed(channel, messages.clearance(k), library)
    return frame(
        run_id,
        np.repeat(t, k),
        {
            "body": pl.Series([body], dtype=pl.String).new_from_index(0, t.size * k),
            "surface": pl.Series(surfaces * t.size, dtype=pl.String),
            "clearance_m": v.reshape(-1),
        },
    )


def _names(value: str | None) -> list[str] | None:
    """A JSON list of names in a channel's metadata (None when it is not one)."""
    try:
        names: list[str] = adapter(list[Text]).validate_json(value or "")
    except ValueError:
        return None
    return names


def contacts(run_id: str, channel: ChannelData) -> pl.DataFrame:
    """A contact channel -> one row per contact point: `/contacts` (format 3: its sides named
    by the channel's metadata, a flex's name on both) or one pair's `/contacts/<g1>/<g2>`."""
    t, data = payloads(channel)
    if channel.schema == logformat.CONTACTS_SCHEMA:
        records, counts = messages.contact_points(data) or _library_points(data)
        names = {k: _names(channel.metadata.get(k)) or [] for k in ("geoms", "bodies", "flexes")}
        text = {  # geom1, geom2, body1, body2
            f"{kind}{k}": _side_names(records[f"geom{k}"], names[table], names["flexes"])
            for kind, table in (("geom", "geoms"), ("body", "bodies"))
            for k in (1, 2)
        }
    else:  # formats 1, 2: one pair's `Contact`, its names in each message
        many = [pb.Contact.FromString(d) for d in data]
        records = _records([m.points for m in many])
        counts = np.array([len(m.points) for m in many], np.int64)
        text = {
            key: pl.Series([getattr(m, key) for m in many for _ in m.points], dtype=pl.String)
            for key in ("geom1", "geom2", "body1", "body2")
        }
    start = np.repeat(np.cumsum(counts) - counts, counts)
    return frame(
        run_id,
        np.repeat(t, counts),
        {
            **text,
            "point": pl.Series(np.arange(start.size) - start, dtype=pl.Int32),
            **{f: records[f].astype(np.float64) for f in POINT_FIELDS},
        },
    )


def _library_points(data: Sequence[bytes]) -> tuple[np.ndarray, np.ndarray]:
    """`Contacts` payloads of another layout, by the protobuf library."""
    many = [pb.Contacts.FromString(d).points for d in data]
    return _records(many), np.array([len(p) for p in many], np.int64)


def _records(points: Sequence[Sequence[Any]]) -> np.ndarray:
    """ContactPoint messages as `POINT_RECORD`s (sides and values)."""
    flat = [p for group in points for p in group]
    out = np.zeros(len(flat), POINT_RECORD)
    for name in (*POINT_FIELDS, "geom1", "geom2"):
        out[name] = [getattr(p, name, 0) for p in flat]
    return out


def _side_names(ids: np.ndarray, geoms: list[str], flexes: list[str]) -> pl.Series:
    """Names of contact sides: geom ids into `geoms`, -1 - flex ids into `flexes` ("" when
    the metadata does not name it)."""
    table = pl.Series([*geoms, *flexes[::-1], ""], dtype=pl.String)
    ids = ids.astype(np.int64)
    at = np.where(ids >= 0, ids, len(geoms) + len(flexes) + ids)  # -1 -> the last flex name
    return table.gather(np.where((ids < len(geoms)) & (ids >= -len(flexes)), at, len(table) - 1))


def impacts(run_id: str, channel: ChannelData) -> pl.DataFrame:
    """`/impacts` -> one row per contact episode (`IMPACT_SCHEMA`)."""
    rows = []
    for data in payloads(channel)[1]:
        i = pb.Impact.FromString(data)
        vectors = [
            list(v) if len(v) == 3 else [None] * 3
            for v in (i.point_in, i.normal_in, i.point_out, i.normal_out)
        ]
        states = [
            list(s.values) if len(s.values) == len(BODY_FIELDS) else [None] * len(BODY_FIELDS)
            for s in (i.side1_in, i.side2_in, i.side1_out, i.side2_out)
        ]
        scalars = (getattr(i, f.name) for f in IMPACT_SCALARS)
        rows.append((run_id, *scalars, *(x for v in (*vectors, *states) for x in v)))
    return pl.DataFrame(rows, schema=IMPACT_SCHEMA, orient="row")


def events(run_id: str, channel: ChannelData | None) -> pl.DataFrame:
    """foxglove.Log messages -> (run_id, t_ns, level, message)."""
    t, data = payloads(channel) if channel is not None else (np.empty(0, np.int64), [])
    logs = [Log.FromString(d) for d in data]
    return pl.DataFrame(
        {
            "run_id": pl.Series([run_id] * len(logs), dtype=pl.String),
            "t_ns": pl.Series(t, dtype=pl.Int64),
            "level": pl.Series([Log.Level.Name(m.level) for m in logs], dtype=pl.String),
            "message": pl.Series([m.message for m in logs], dtype=pl.String),
        }
    )
