"""Fixed layouts (`codec.Template`) of the log's per-step messages, shared by record and analyze.

Value orders:
- BodyState: x y z, qw qx qy qz, vx vy vz, wx wy wz (`BODY_FIELDS`).
- Energy: kinetic potential total.
- Work: the fields of `impactlab.Work` in number order (`WORK_FIELDS`).
- Clearance: one distance per surface, in the order of the channel's `surfaces`.
- ContactPoint: the fields of `impactlab.ContactPoint` in number order (`POINT_FIELDS`).
- FrameTransforms: per body tx ty tz, qw qx qy qz; each transform's timestamp is the message's
  log time (`stamped_transforms`).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from functools import cache

import numpy as np
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from google.protobuf.message import Message

from impactlab.logs import format as logformat
from impactlab.logs.codec import Template
from impactlab.proto import impactlab_pb2 as pb

BODY_FIELDS = ("x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz")
ENERGY_FIELDS = ("kinetic", "potential", "total")
POINT_FIELDS = tuple(f.name for f in pb.ContactPoint.DESCRIPTOR.fields if f.type == f.TYPE_DOUBLE)
WORK_FIELDS = tuple(f.name for f in pb.Work.DESCRIPTOR.fields)


def _set_fields(names: Sequence[str]) -> Callable[[Message, Sequence[float]], None]:
    def setter(msg: Message, values: Sequence[float]) -> None:
        for name, value in zip(names, values, strict=True):
            setattr(msg, name, value)

    return setter


@cache
def body_state() -> Template:
    """Layout of `impactlab.BodyState`."""
    return Template.learn(pb.BodyState, _set_fields(BODY_FIELDS), len(BODY_FIELDS))


@cache
def energy() -> Template:
    """Layout of `impactlab.Energy`."""
    return Template.learn(pb.Energy, _set_fields(ENERGY_FIELDS), len(ENERGY_FIELDS))


@cache
def work() -> Template:
    """Layout of `impactlab.Work`."""
    return Template.learn(pb.Work, _set_fields(WORK_FIELDS), len(WORK_FIELDS))


@cache
def clearance(k: int) -> Template:
    """Layout of `impactlab.Clearance` with k distances."""

    def setter(msg: pb.Clearance, values: Sequence[float]) -> None:
        msg.distance.extend(values)

    return Template.learn(pb.Clearance, setter, k)


def _point_record() -> np.dtype:
    """One `ContactPoint` inside `Contacts` as bytes: its tag and length, then each field's
    tag and value (doubles, then the two sides' int32), checked against the protobuf library
    (a point written with every field set: the same bytes, or the layout is refused)."""
    fields = [("tag", "u1"), ("len", "u1")]
    for name in POINT_FIELDS:
        fields += [(f"t_{name}", "u1"), (name, "<f8")]
    fields += [("t_geom1", "u1"), ("geom1", "<i4"), ("t_geom2", "u1"), ("geom2", "<i4")]
    record = np.dtype(fields)
    probe = np.zeros(1, record)
    for i, name in enumerate(POINT_FIELDS):
        probe[f"t_{name}"] = (pb.ContactPoint.DESCRIPTOR.fields_by_name[name].number << 3) | 1
        probe[name] = 1.0 + i
    probe["t_geom1"], probe["geom1"] = (14 << 3) | 5, -7
    probe["t_geom2"], probe["geom2"] = (15 << 3) | 5, 9
    probe["tag"], probe["len"] = (1 << 3) | 2, record.itemsize - 2
    message = pb.Contacts()
    point = message.points.add(geom1=-7, geom2=9)
    for i, name in enumerate(POINT_FIELDS):
        setattr(point, name, 1.0 + i)
    if probe.tobytes() != message.SerializeToString():
        raise RuntimeError("impactlab.ContactPoint does not have the layout this reader knows")
    return record


POINT_RECORD = _point_record()


def contact_payloads(row: np.ndarray, sides: np.ndarray, values: np.ndarray) -> list[bytes]:
    """`Contacts` payloads, one per logged row with contacts (rows ascending): the points'
    rows (m,), sides (m, 2) int and values (m, 13) in `POINT_FIELDS` order, by row."""
    records = np.zeros(row.size, POINT_RECORD)
    records["tag"], records["len"] = (1 << 3) | 2, POINT_RECORD.itemsize - 2
    for i, name in enumerate(POINT_FIELDS):
        records[f"t_{name}"] = (i + 1) << 3 | 1
        records[name] = values[:, i]
    records["t_geom1"], records["geom1"] = (14 << 3) | 5, sides[:, 0]
    records["t_geom2"], records["geom2"] = (15 << 3) | 5, sides[:, 1]
    flat = records.view(np.uint8)
    size = POINT_RECORD.itemsize
    bounds = np.flatnonzero(np.r_[True, np.diff(row) != 0, True])
    return [flat[a * size : b * size].tobytes() for a, b in itertools.pairwise(bounds)]


def contact_points(payloads: Sequence[bytes]) -> tuple[np.ndarray, np.ndarray] | None:
    """The points of `Contacts` payloads: records (m,) of `POINT_RECORD` and each payload's
    point count; None when any payload is not in this layout (then read them one by one)."""
    size = POINT_RECORD.itemsize
    counts = np.fromiter((len(p) for p in payloads), np.int64, len(payloads))
    if (counts % size).any():
        return None
    records = np.frombuffer(b"".join(payloads), POINT_RECORD)
    tags = [records["tag"] == 10, records["len"] == size - 2]
    tags += [records[f"t_{n}"] == (i + 1) << 3 | 1 for i, n in enumerate(POINT_FIELDS)]
    tags += [records["t_geom1"] == (14 << 3) | 5, records["t_geom2"] == (15 << 3) | 5]
    if not np.logical_and.reduce(tags).all():
        return None
    return records, counts // size


@cache
def transforms(bodies: tuple[str, ...], stamp: tuple[int, int] = (0, 0)) -> Template:
    """Layout of `foxglove.FrameTransforms`, world -> each body, every transform stamped with
    `stamp` (seconds, nanos): the payloads of other stamps whose varints have the same lengths
    differ only in the stamp's bytes (`stamped_transforms`)."""

    def setter(msg: FrameTransforms, values: Sequence[float]) -> None:
        for i, name in enumerate(bodies):
            tf = msg.transforms.add()
            tf.timestamp.seconds, tf.timestamp.nanos = stamp
            tf.parent_frame_id = logformat.WORLD_FRAME
            tf.child_frame_id = name
            v = values[7 * i : 7 * i + 7]
            tf.translation.x, tf.translation.y, tf.translation.z = v[0:3]
            tf.rotation.w, tf.rotation.x, tf.rotation.y, tf.rotation.z = v[3:7]

    return Template.learn(FrameTransforms, setter, 7 * len(bodies))


def _varint_length(v: np.ndarray) -> np.ndarray:
    """Bytes of each non-negative value's protobuf varint; 0 for 0 (proto3 omits the field)."""
    bits = np.zeros(v.shape, np.int64)
    nz = v > 0
    bits[nz] = np.floor(np.log2(v[nz].astype(np.float64))).astype(np.int64) + 1
    bits[nz & (v >= (1 << 53))] = 64  # beyond float precision: count exactly below
    length = (bits + 6) // 7
    big = np.flatnonzero(bits == 64)
    length[big] = [len(_varint(int(x))) for x in v[big]]
    return length


def _varint(x: int) -> bytes:
    out = bytearray()
    while True:
        out.append((x & 0x7F) | (0x80 if x > 0x7F else 0))
        x >>= 7
        if not x:
            return bytes(out)


def _varint_bytes(v: np.ndarray, n: int) -> np.ndarray:
    """Each value's varint of exactly n bytes, (len(v), n) uint8."""
    v = v.astype(np.uint64)
    shifts = (7 * np.arange(n)).astype(np.uint64)
    out = ((v[:, None] >> shifts) & np.uint64(0x7F)).astype(np.uint8)
    out[:, : n - 1] |= 0x80
    return out


def stamped_transforms(
    bodies: tuple[str, ...], t_ns: np.ndarray, poses: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """`foxglove.FrameTransforms` payloads whose transforms carry their row's time.

    Args:
        t_ns: row times, ns, (n,) (non-negative).
        poses: per row and body tx ty tz qw qx qy qz, (n, 7 nbody).

    Returns:
        (row indices, payloads (k, L) uint8) per group of rows whose stamps' varints have
        the same lengths (a handful: the layout is otherwise fixed).
    """
    t = np.asarray(t_ns, np.int64)
    sec, nanos = t // 1_000_000_000, t % 1_000_000_000
    ls, ln = _varint_length(sec), _varint_length(nanos)
    out = []
    key = ls * 8 + ln
    # the keys present, without np.unique (its first call imports numpy.ma, 40 ms in each
    # forked record worker): a key is at most 10 * 8 + 5
    for k in np.flatnonzero(np.bincount(key.ravel())).tolist():
        a, b = divmod(k, 8)
        rows = np.flatnonzero(key == k)
        probe = ((1 << (7 * a - 7)) if a else 0, (1 << (7 * b - 7)) if b else 0)
        layout = transforms(bodies, probe)
        payloads = layout.encode(poses[rows])
        if a or b:
            stamp = np.concatenate(
                [
                    np.full((rows.size, 1 if a else 0), 0x08, np.uint8),
                    _varint_bytes(sec[rows], a),
                    np.full((rows.size, 1 if b else 0), 0x10, np.uint8),
                    _varint_bytes(nanos[rows], b),
                ],
                axis=1,
            )
            for at in _stamp_offsets(bodies, probe, stamp.shape[1]):
                payloads[:, at : at + stamp.shape[1]] = stamp
        out.append((rows, payloads))
    return out


@cache
def _stamp_offsets(bodies: tuple[str, ...], probe: tuple[int, int], size: int) -> tuple[int, ...]:
    """Where each transform's stamp bytes lie in the payload of `transforms(bodies, probe)`:
    the bytes that change when the stamp does: the probe (the smallest values of their varint
    lengths) and the largest values of the same lengths differ in their first byte."""
    a = transforms(bodies, probe).template
    other = (
        (probe[0] << 7) - 1 if probe[0] else 0,
        min((probe[1] << 7) - 1, 999_999_999) if probe[1] else 0,
    )
    b = transforms(bodies, other).template
    differ = np.flatnonzero(a != b)
    starts: list[int] = []
    for i in differ.tolist():
        if not starts or i >= starts[-1] + size:
            starts.append(i)
    # the stamp starts one byte before its first changed byte (the field tag)
    offsets = tuple(s - 1 for s in starts)
    assert len(offsets) == len(bodies), "FrameTransforms layout changed"
    return offsets
