"""Decode a log's gathered records into polars frames: fixed layouts as arrays, the rest by
the protobuf library."""

from __future__ import annotations

import functools
import json
from collections import defaultdict
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import polars as pl

from impactlab.logs import messages
from impactlab.logs.codec import Template
from impactlab.logs.messages import BODY_FIELDS, POINT_FIELDS
from impactlab.logs.reader import ChannelData
from impactlab.proto import impactlab_pb2 as pb


def decode_fixed(
    channel: ChannelData, layout: Template, fallback: Callable[[bytes], list[float]]
) -> tuple[np.ndarray, np.ndarray]:
    """A channel's times (n,) and values (n, k), sorted by time.

    Pieces in the template's layout are decoded as arrays; anything else goes through the
    protobuf library (`fallback` turns one payload into its values).
    """
    pieces = channel.pieces
    n = sum(len(t) for t, _ in pieces)
    out = np.empty((layout.slots.size, n), dtype=np.float64)  # a column per value
    at = 0
    for t, data in pieces:
        block = out[:, at : at + len(t)]
        if not (isinstance(data, np.ndarray) and layout.decode_into(data, block)):
            rows = data if isinstance(data, list) else [bytes(r) for r in data]
            block[:] = (
                np.asarray([fallback(r) for r in rows], dtype=np.float64).reshape(len(t), -1).T
            )
        at += len(t)
    if len(pieces) == 1:
        t_all = pieces[0][0]
    else:
        t_all = np.concatenate([t for t, _ in pieces]) if pieces else np.empty(0, np.int64)
    t_all, v_all = t_all.astype(np.int64, copy=False), out.T
    if (np.diff(t_all) >= 0).all():
        return t_all, v_all
    order = np.argsort(t_all, kind="stable")
    return t_all[order], v_all[order]


def body_state_values(data: bytes) -> list[float]:
    m = pb.BodyState.FromString(data)
    return [getattr(m, f) for f in BODY_FIELDS]


def energy_values(data: bytes) -> list[float]:
    m = pb.Energy.FromString(data)
    return [m.kinetic, m.potential, m.total]


def loose_payloads(channel: ChannelData) -> tuple[np.ndarray, list[bytes]]:
    """A channel's messages as (times, payload bytes), sorted by time."""
    times, payloads = [], []
    for t, data in channel.pieces:
        times += t.tolist()
        payloads += data if isinstance(data, list) else [bytes(r) for r in data]
    order = np.argsort(np.asarray(times, dtype=np.int64), kind="stable")
    return np.asarray(times, dtype=np.int64)[order], [payloads[i] for i in order]


def decode_contacts(run_id: str, channel: ChannelData) -> pl.DataFrame:
    """A `/contacts` channel (format 3) -> one row per contact point, by time: its sides'
    geom and party names from the channel's metadata (a flex's name on both)."""
    t_ns, payloads = loose_payloads(channel)
    found = messages.contact_points(payloads)
    if found is None:  # another writer's layout: the protobuf library, message by message
        return _contact_frame_slow(run_id, t_ns, payloads, channel.metadata)
    records, counts = found
    meta = channel.metadata
    geoms, bodies, flexes = (_names(meta.get(k)) for k in ("geoms", "bodies", "flexes"))
    t = np.repeat(t_ns, counts)
    point = np.arange(t.size) - np.repeat(np.cumsum(counts) - counts, counts)
    out = [pl.Series("run_id", [run_id] * t.size, dtype=pl.String)]
    out += [pl.Series("t_ns", t, dtype=pl.Int64), pl.Series("t_s", t / 1e9)]
    for side in ("geom1", "geom2"):
        ids = records[side].astype(np.int64)
        out.append(pl.Series(side, _side_names(ids, geoms, flexes), dtype=pl.String))
    for k, side in enumerate(("geom1", "geom2")):
        ids = records[side].astype(np.int64)
        out.append(pl.Series(f"body{k + 1}", _side_names(ids, bodies, flexes), dtype=pl.String))
    out.append(pl.Series("point", point, dtype=pl.Int32))
    out += [pl.Series(f, records[f].astype(np.float64)) for f in POINT_FIELDS]
    return pl.DataFrame(out)


def _names(value: str | None) -> list[str]:
    try:
        names = json.loads(value or "[]")
    except ValueError:
        return []
    return [str(n) for n in names] if isinstance(names, list) else []


def _side_names(ids: np.ndarray, geoms: list[str], flexes: list[str]) -> list[str]:
    """Names of contact sides: geom ids into `geoms`, -1 - flex ids into `flexes` ("" when
    the metadata does not name it)."""
    table = np.array([*geoms, *flexes[::-1], ""], dtype=object)
    at = np.where(ids >= 0, ids, len(geoms) + len(flexes) + ids)  # -1 -> the last flex name
    at = np.where((ids < len(geoms)) & (ids >= -len(flexes)), at, len(table) - 1)
    return list(table[at])


def _contact_frame_slow(
    run_id: str,
    t_ns: np.ndarray,
    payloads: Sequence[bytes],
    meta: dict[str, str] | None = None,
) -> pl.DataFrame:
    """Contact payloads by the protobuf library: `Contacts` (format 3, sides named by
    `meta`) or one pair's `Contact` (formats 1, 2)."""
    cols: dict[str, list[Any]] = defaultdict(list)
    if meta is not None:
        geoms, bodies, flexes = (_names(meta.get(k)) for k in ("geoms", "bodies", "flexes"))
    for t, data in zip(t_ns.tolist(), payloads, strict=True):
        if meta is not None:
            many = pb.Contacts.FromString(data)
            points = list(many.points)
            ids = np.array([[p.geom1, p.geom2] for p in points], np.int64).reshape(-1, 2)
            names = [_side_names(ids[:, k], geoms, flexes) for k in (0, 1)]
            parties = [_side_names(ids[:, k], bodies, flexes) for k in (0, 1)]
            sides = list(zip(names[0], names[1], parties[0], parties[1], strict=True))
        else:
            m = pb.Contact.FromString(data)
            points = list(m.points)
            sides = [(m.geom1, m.geom2, m.body1, m.body2)] * len(points)
        for i, (p, (g1, g2, b1, b2)) in enumerate(zip(points, sides, strict=True)):
            cols["t_ns"].append(t)
            cols["geom1"].append(g1)
            cols["geom2"].append(g2)
            cols["body1"].append(b1)
            cols["body2"].append(b2)
            cols["point"].append(i)
            for f in POINT_FIELDS:
                cols[f].append(getattr(p, f))
    if not cols:
        return empty_contacts(run_id)
    frame = pl.DataFrame(dict(cols)).with_columns(
        pl.col("t_ns").cast(pl.Int64), pl.col("point").cast(pl.Int32)
    )
    return frame.select(
        pl.lit(run_id).alias("run_id"),
        "t_ns",
        pl.Series("t_s", frame["t_ns"].to_numpy() / 1e9),  # as the fast path (numpy division)
        *frame.columns[1:],
    )


def decode_pair_contacts(run_id: str, channel: ChannelData) -> pl.DataFrame:
    """A formats 1, 2 `/contacts/<geom1>/<geom2>` channel -> one row per contact point."""
    t_ns, payloads = loose_payloads(channel)
    return _contact_frame_slow(run_id, t_ns, payloads)


def decode_clearance(
    run_id: str, channel: ChannelData, columns: Columns | None = None
) -> pl.DataFrame:
    """A Clearance channel -> one row per logged step and surface (long format).

    The channel's metadata names the body and (JSON) the surfaces in value order.

    Raises:
        ValueError: the metadata does not name the body and its surfaces.
    """
    import json

    body = channel.metadata.get("body", "")
    try:
        surfaces = json.loads(channel.metadata.get("surfaces", ""))
    except ValueError:
        surfaces = None
    if not body or not isinstance(surfaces, list) or not all(isinstance(s, str) for s in surfaces):
        raise ValueError("the channel's metadata does not name its body and surfaces")
    k = len(surfaces)

    def fallback(data: bytes) -> list[float]:
        values = list(pb.Clearance.FromString(data).distance)
        if len(values) != k:
            raise ValueError(f"{len(values)} distances for {k} surfaces")
        return values

    columns = Columns() if columns is None else columns
    t, values = decode_fixed(channel, messages.clearance(k), fallback)
    n = len(t)
    t_rep = np.repeat(t, k) if k != 1 else t
    if k == 1:
        surface = columns.constant(surfaces[0], n, "surface")
    else:
        names = pl.Series("surface", surfaces, dtype=pl.String)
        surface = names.gather(np.tile(np.arange(k), n)) if n else names.clear()
    return pl.DataFrame(
        [
            columns.constant(run_id, n * k, "run_id"),
            *columns.times(t_rep),
            columns.constant(body, n * k, "body"),
            surface,
            pl.Series("clearance_m", values.reshape(-1) if n else np.empty(0), dtype=pl.Float64),
        ]
    )


IMPACT_SCHEMA: dict[str, Any] = {
    "run_id": pl.String,
    **{k: pl.String for k in ("side1", "kind1", "side2", "kind2", "geom1", "geom2")},
    "onset_ns": pl.Int64,
    "release_ns": pl.Int64,
    "v_in_mps": pl.Float64,
    "v_out_mps": pl.Float64,
    "work_compression_J": pl.Float64,
    "work_restitution_J": pl.Float64,
    "work_friction_J": pl.Float64,
    "peak_force_N": pl.Float64,
    "impulse_Ns": pl.Float64,
    "max_penetration_m": pl.Float64,
    "steps": pl.Int64,
    "open": pl.Boolean,
    **{f"{v}{c}_{w}": pl.Float64 for w in ("in", "out") for v in ("p", "n") for c in "xyz"},
    **{f"s{k}_{w}_{f}": pl.Float64 for w in ("in", "out") for k in (1, 2) for f in BODY_FIELDS},
}
"""The `/impacts` frame: one row per contact episode (`impactlab.Impact`): point and
normal at the first and last step (`px_in`, ..., `nz_out`), each side's state at the first
step in contact and the first after (`s1_in_x`, ..., `s2_out_wz`; null for a side that is
not a rigid body)."""


def decode_impacts(run_id: str, payloads: Sequence[bytes]) -> pl.DataFrame:
    """`/impacts` payloads -> one row per contact episode (`IMPACT_SCHEMA`)."""
    rows = []
    nan13 = [None] * len(BODY_FIELDS)
    for data in payloads:
        i = pb.Impact.FromString(data)
        names = (i.side1, i.kind1, i.side2, i.kind2, i.geom1, i.geom2)
        numbers = (
            i.onset_ns,
            i.release_ns,
            i.v_in,
            i.v_out,
            i.work_compression,
            i.work_restitution,
            i.work_friction,
            i.peak_force,
            i.impulse,
        )
        vectors = [
            list(v) if len(v) == 3 else [None] * 3
            for v in (i.point_in, i.normal_in, i.point_out, i.normal_out)
        ]
        states = [
            list(s.values) if len(s.values) == len(BODY_FIELDS) else nan13
            for s in (i.side1_in, i.side2_in, i.side1_out, i.side2_out)
        ]
        flat = [x for v in (*vectors, *states) for x in v]
        rows.append((run_id, *names, *numbers, i.max_penetration, i.steps, i.open, *flat))
    return pl.DataFrame(rows, schema=IMPACT_SCHEMA, orient="row")


def empty_impacts(run_id: str) -> pl.DataFrame:
    """An impacts frame with no rows."""
    return pl.DataFrame(schema=IMPACT_SCHEMA)


def empty_clearance(run_id: str) -> pl.DataFrame:
    """A clearance frame with no rows."""
    schema: dict[str, Any] = {"run_id": pl.String, "t_ns": pl.Int64, "t_s": pl.Float64}
    schema |= {"body": pl.String, "surface": pl.String, "clearance_m": pl.Float64}
    return pl.DataFrame(schema=schema)


def decode_events(run_id: str, t_ns: np.ndarray, payloads: Sequence[bytes]) -> pl.DataFrame:
    """foxglove.Log payloads -> (run_id, t_ns, level, message)."""
    from foxglove_schemas_protobuf.Log_pb2 import Log

    levels, messages = [], []
    for data in payloads:
        m = Log.FromString(data)
        levels.append(Log.Level.Name(m.level))
        messages.append(m.message)
    return pl.DataFrame(
        [
            _constant(run_id, len(levels), "run_id"),
            pl.Series("t_ns", t_ns, dtype=pl.Int64),
            pl.Series("level", levels, dtype=pl.String),
            pl.Series("message", messages, dtype=pl.String),
        ]
    )


def _constant(value: str, n: int, name: str = "") -> pl.Series:
    """A string column of one value (eager: no query plan per column)."""
    return _one(value).new_from_index(0, n).alias(name)


@functools.lru_cache(maxsize=256)
def _one(value: str) -> pl.Series:
    """A one-row string Series (only ever copied: a log's frames repeat the same values)."""
    return pl.Series("", [value], dtype=pl.String)


class Columns:
    """The columns a log's frames repeat, each built once: a constant string column is a
    slice of the longest one of that value, and frames of the same times share their
    `t_ns` and `t_s` (less to build, and less fresh memory: a page fault per 4 KiB)."""

    def __init__(self) -> None:
        self._strings: dict[str, pl.Series] = {}
        self._times: list[tuple[np.ndarray, pl.Series, pl.Series]] = []

    def constant(self, value: str, n: int, name: str) -> pl.Series:
        """A string column of `n` times `value`."""
        built = self._strings.get(value)
        if built is None or len(built) < n:
            built = self._strings[value] = _constant(value, n)
        return (built if len(built) == n else built.slice(0, n)).alias(name)

    def times(self, t_ns: np.ndarray) -> tuple[pl.Series, pl.Series]:
        """Columns `t_ns` (int64) and `t_s` (`t_ns` / 1e9) of times (n,) int64."""
        for t, ns, s in self._times:
            if t is t_ns or (len(t) == len(t_ns) and np.array_equal(t, t_ns)):
                return ns, s
        ns = pl.Series("t_ns", t_ns.astype(np.int64, copy=False))
        s = pl.Series("t_s", t_ns / 1e9)
        self._times.append((t_ns, ns, s))
        return ns, s


def fixed_frame(
    run_id: str,
    t_ns: np.ndarray,
    values: np.ndarray,
    names: Sequence[str],
    columns: Columns | None = None,
) -> pl.DataFrame:
    """Frame (run_id, t_ns, t_s, *names) of times (n,) int64 and values (n, k)."""
    columns = Columns() if columns is None else columns
    return pl.DataFrame(
        [
            columns.constant(run_id, len(t_ns), "run_id"),
            *columns.times(t_ns),
            *_float_columns(values.T, names),
        ]
    )


def _float_columns(rows: np.ndarray, names: Sequence[str]) -> list[pl.Series]:
    """Float64 columns from `rows`, (k, n), a row per column: one Series over all of them
    (no copy when `rows` is C-contiguous), sliced (polars builds each Series in Python,
    a slice is one call)."""
    n = rows.shape[1]
    flat = pl.Series(np.ascontiguousarray(rows, dtype=np.float64).reshape(-1))
    return [flat.slice(i * n, n).alias(name) for i, name in enumerate(names)]


def empty_frame(names: Sequence[str], run_id: str) -> pl.DataFrame:
    """A frame of `fixed_frame`'s columns with no rows."""
    return _empty_fixed(tuple(names)).clear()


@functools.cache
def _empty_fixed(names: tuple[str, ...]) -> pl.DataFrame:
    return fixed_frame("", np.empty(0, np.int64), np.empty((0, len(names))), names)


def empty_contacts(run_id: str) -> pl.DataFrame:
    """A contact frame with no rows (a new one each time, from one built once)."""
    return _no_contacts().clear()


@functools.cache
def _no_contacts() -> pl.DataFrame:
    schema: dict[str, Any] = {"run_id": pl.String, "t_ns": pl.Int64, "t_s": pl.Float64}
    schema |= {k: pl.String for k in ("geom1", "geom2", "body1", "body2")}
    schema["point"] = pl.Int32
    schema |= {f: pl.Float64 for f in POINT_FIELDS}
    return pl.DataFrame(schema=schema)
