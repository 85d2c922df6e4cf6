"""The log's per-step messages as arrays: fixed protobuf layouts encoded and decoded by numpy."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cache, cached_property

import numpy as np
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from google.protobuf.message import Message

from impactlab.logs import format as logformat
from impactlab.proto import impactlab_pb2 as pb

BODY_FIELDS = ("x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz")
ENERGY_FIELDS = ("kinetic", "potential", "total")
POINT_FIELDS = tuple(f.name for f in pb.ContactPoint.DESCRIPTOR.fields if f.type == f.TYPE_DOUBLE)
WORK_FIELDS = tuple(f.name for f in pb.Work.DESCRIPTOR.fields)


MAX_RUNS = 16
"""A layout with more runs of evenly spaced doubles (a transform per body) is encoded by one
gather of every value's bytes instead of a copy per run."""


@dataclass(frozen=True)
class Template:
    """A message whose only varying fields are doubles, all written: its bytes `template`
    (size,) uint8 with zeros where the doubles go, their offsets `slots` (k,), and `fixed`,
    the bytes every payload of this layout has (so another layout is never misread)."""

    template: np.ndarray
    slots: np.ndarray
    fixed: np.ndarray

    @property
    def size(self) -> int:
        """Payload length in bytes."""
        return int(self.template.size)

    @classmethod
    def learn(
        cls, msg: Message, setter: Callable[[Message, Sequence[float]], None], k: int
    ) -> Template:
        """The layout of `msg` with its k doubles set by `setter(msg, values)`, learnt from
        the protobuf library with distinct sentinels; ValueError when one is missing."""
        if k >= 2**20:
            raise ValueError(f"{k:,} doubles in one message: more than a layout can learn")
        sentinels = [1.0 + (i + 1) * 2.0**-20 + 2.0**-40 for i in range(k)]
        setter(msg, sentinels)
        raw = msg.SerializeToString()
        data = np.frombuffer(raw, np.uint8)
        if k == 0:  # nothing varies (e.g. the transforms of a model with no moving body)
            return cls(data.copy(), np.empty(0, np.int64), np.ones(data.size, bool))
        # every 8 bytes that may hold a sentinel (a double in [1, 2): its top bytes 0x3FFx)
        starts = np.flatnonzero((data[7:] == 0x3F) & (data[6:-1] >= 0xF0))
        found = np.lib.stride_tricks.sliding_window_view(data, 8)[starts].copy().view("<f8")[:, 0]
        index = np.rint((found - 1.0 - 2.0**-40) * 2.0**20).astype(np.int64) - 1
        hit = (index >= 0) & (index < k)
        hit[hit] = found[hit] == np.asarray(sentinels)[index[hit]]
        slots = np.full(k, -1, np.int64)
        slots[index[hit]] = starts[hit]  # in value order, wherever the protobuf library put it
        if (slots < 0).any():
            raise ValueError("message layout is not fixed: a double is missing")
        template, fixed = data.copy(), np.ones(data.size, bool)
        varying = (slots[:, None] + np.arange(8)).ravel()
        template[varying], fixed[varying] = 0, False
        layout = cls(template, slots, fixed)
        if layout.encode(np.array([sentinels])).tobytes() != raw:
            raise ValueError("message layout is not fixed: a double is repeated")
        return layout

    @cached_property
    def _runs(self) -> list[tuple[int, int, int, int]]:
        """The doubles in runs of even spacing: (first value, count, byte offset, spacing)."""
        runs, slots, j = [], self.slots.tolist(), 0
        while j < len(slots):
            step = slots[j + 1] - slots[j] if j + 1 < len(slots) else 8
            step = step if step > 0 else 8  # a run goes forward in the payload
            n = 1
            while j + n < len(slots) and slots[j + n] - slots[j + n - 1] == step:
                n += 1
            runs.append((j, n, slots[j], step))
            j += n
        return runs

    def _numbers(self, payloads: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """Per run, its first value and a (n, count) float64 view of C-ordered payloads."""
        rows, m = payloads.strides[0], len(payloads)
        return [
            (j, np.ndarray((m, n), "<f8", payloads, at, (rows, step)) if m else np.empty((0, n)))
            for j, n, at, step in self._runs
        ]

    @cached_property
    def _bytes(self) -> np.ndarray:
        """Every double's bytes' offsets, (k * 8,): for layouts of many runs."""
        return (self.slots[:, None] + np.arange(8)).ravel()

    def encode(self, values: np.ndarray) -> np.ndarray:
        """Payloads of rows of doubles: (n, k) float64 -> (n, size) uint8."""
        out = np.tile(self.template, (len(values), 1))
        if len(self._runs) > MAX_RUNS:  # one copy of every value's bytes
            doubles = np.ascontiguousarray(values, "<f8")
            out[:, self._bytes] = doubles.view(np.uint8).reshape(len(values), -1)
            return out
        for j, view in self._numbers(out):
            view[:] = values[:, j : j + view.shape[1]]
        return out

    def decode(self, payloads: np.ndarray) -> np.ndarray | None:
        """Doubles of payloads: (n, size) uint8 -> (n, k) float64 (each value's column
        contiguous); None when any payload is of another layout."""
        if payloads.ndim != 2 or payloads.shape[1] != self.size:
            return None
        if not (payloads[:, self.fixed] == self.template[self.fixed]).all():
            return None
        out = np.empty((self.slots.size, len(payloads)))
        for j, view in self._numbers(np.ascontiguousarray(payloads)):
            out[j : j + view.shape[1]] = view.T
        return out.T


def _setter(names: Sequence[str]) -> Callable[[Message, Sequence[float]], None]:
    def setter(msg: Message, values: Sequence[float]) -> None:
        for name, value in zip(names, values, strict=True):
            setattr(msg, name, value)

    return setter


@cache
def body_state() -> Template:
    """Layout of `impactlab.BodyState`."""
    return Template.learn(pb.BodyState(), _setter(BODY_FIELDS), len(BODY_FIELDS))


@cache
def energy() -> Template:
    """Layout of `impactlab.Energy`."""
    return Template.learn(pb.Energy(), _setter(ENERGY_FIELDS), len(ENERGY_FIELDS))


@cache
def work() -> Template:
    """Layout of `impactlab.Work`."""
    return Template.learn(pb.Work(), _setter(WORK_FIELDS), len(WORK_FIELDS))


@cache
def clearance(k: int) -> Template:
    """Layout of `impactlab.Clearance` with k distances."""
    return Template.learn(pb.Clearance(), lambda m, v: m.distance.extend(v), k)


def _point_record() -> np.dtype:
    """One `ContactPoint` inside `Contacts`: its tag and length, then each field's tag and
    value (the doubles, then the sides' int32), checked against the protobuf library."""
    fields = [("tag", "u1"), ("len", "u1")]
    for name in POINT_FIELDS:
        fields += [(f"t_{name}", "u1"), (name, "<f8")]
    record = np.dtype(
        [*fields, ("t_geom1", "u1"), ("geom1", "<i4"), ("t_geom2", "u1"), ("geom2", "<i4")]
    )
    probe = _points(
        np.zeros(1, int), np.array([[-7, 9]]), 1.0 + np.arange(len(POINT_FIELDS))[None], record
    )
    message = pb.Contacts()
    point = message.points.add(geom1=-7, geom2=9)
    for i, name in enumerate(POINT_FIELDS):
        setattr(point, name, 1.0 + i)
    if probe.tobytes() != message.SerializeToString():
        raise RuntimeError("impactlab.ContactPoint does not have the layout this reader knows")
    return record


def _points(row: np.ndarray, sides: np.ndarray, values: np.ndarray, record: np.dtype) -> np.ndarray:
    """Points as records: `_tags(record)`, sides (m, 2) and values (m, 13) filled in."""
    out = np.empty(row.size, record)  # every byte is written below
    for name, tag in _tags(record).items():
        out[name] = tag
    for i, name in enumerate(POINT_FIELDS):
        out[name] = values[:, i]
    out["geom1"], out["geom2"] = sides[:, 0], sides[:, 1]
    return out


def _tags(record: np.dtype) -> dict[str, int]:
    """The fixed bytes of a point record: field tags (wire type 1: 64-bit, 5: 32-bit)."""
    tags = {"tag": (1 << 3) | 2, "len": record.itemsize - 2}
    tags |= {f"t_{n}": (i + 1) << 3 | 1 for i, n in enumerate(POINT_FIELDS)}
    return tags | {"t_geom1": (14 << 3) | 5, "t_geom2": (15 << 3) | 5}


POINT_RECORD = _point_record()


def contact_payloads(
    row: np.ndarray, sides: np.ndarray, values: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """`Contacts` payloads of points (rows (m,) ascending, sides (m, 2): a geom id or -1 - a
    flex id, values (m, 13)), one per row with points, grouped by their number of points:
    (the rows, payloads (k, L) uint8) per group, each group a dense block."""
    flat = _points(row, sides, values, POINT_RECORD).view(np.uint8).reshape(row.size, -1)
    starts = np.flatnonzero(np.r_[True, row[1:] != row[:-1]])
    counts = np.diff(np.r_[starts, row.size])
    groups = []
    for count in np.flatnonzero(np.bincount(counts)).tolist():  # np.unique imports numpy.ma
        first = starts[counts == count]
        points = (first[:, None] + np.arange(count)).ravel()
        groups.append((row[first], flat[points].reshape(first.size, -1)))
    return groups


def contact_points(payloads: Sequence[bytes]) -> tuple[np.ndarray, np.ndarray] | None:
    """The points of `Contacts` payloads: records (m,) of `POINT_RECORD` and each payload's
    point count; None when any payload is not in this layout (read them one by one)."""
    size = POINT_RECORD.itemsize
    counts = np.fromiter(map(len, payloads), np.int64, len(payloads))
    if (counts % size).any():
        return None
    records = np.frombuffer(b"".join(payloads), POINT_RECORD)
    if not all((records[name] == tag).all() for name, tag in _tags(POINT_RECORD).items()):
        return None
    return records, counts // size


@cache
def transforms(bodies: tuple[str, ...], stamp: tuple[int, int] = (0, 0)) -> Template:
    """Layout of `foxglove.FrameTransforms`, world -> each body, each transform stamped with
    (seconds, nanos) `stamp`: other stamps of the same varint lengths differ in its bytes only."""

    def setter(msg: FrameTransforms, values: Sequence[float]) -> None:
        for i, name in enumerate(bodies):
            tf = msg.transforms.add(parent_frame_id=logformat.WORLD_FRAME, child_frame_id=name)
            tf.timestamp.seconds, tf.timestamp.nanos = stamp
            v = values[7 * i : 7 * i + 7]
            tf.translation.x, tf.translation.y, tf.translation.z = v[0:3]
            tf.rotation.w, tf.rotation.x, tf.rotation.y, tf.rotation.z = v[3:7]

    return Template.learn(FrameTransforms(), setter, 7 * len(bodies))


def _varint_length(v: np.ndarray) -> np.ndarray:
    """Bytes of each value's protobuf varint (0 < v < 2^35); 0 for 0 (proto3 omits it)."""
    return np.searchsorted(1 << (7 * np.arange(1, 6)), v, side="right") + (v > 0)


def stamped_transforms(
    bodies: tuple[str, ...], t_ns: np.ndarray, poses: np.ndarray
) -> list[tuple[np.ndarray, np.ndarray]]:
    """`foxglove.FrameTransforms` payloads of poses (n, 7 nbody: tx ty tz qw qx qy qz), each
    transform stamped with its row's time `t_ns` (n,): (rows, payloads (k, L) uint8) per group
    of rows whose stamps' varints have the same lengths (a handful)."""
    sec, nanos = np.divmod(np.asarray(t_ns, np.int64), 1_000_000_000)
    key = _varint_length(sec) * 8 + _varint_length(nanos)
    out = []
    for k in np.flatnonzero(np.bincount(key)).tolist():  # np.unique would import numpy.ma
        a, b = divmod(k, 8)
        rows = np.flatnonzero(key == k)
        probe = ((1 << (7 * a - 7)) if a else 0, (1 << (7 * b - 7)) if b else 0)
        payloads = transforms(bodies, probe).encode(poses[rows])
        if a or b:
            stamp = np.concatenate(_stamp(sec[rows], nanos[rows], a, b), axis=1)
            for at in _stamp_offsets(bodies, probe, stamp.shape[1]):
                payloads[:, at : at + stamp.shape[1]] = stamp
        out.append((rows, payloads))
    return out


def _stamp(sec: np.ndarray, nanos: np.ndarray, a: int, b: int) -> list[np.ndarray]:
    """The stamp's bytes: each present field's tag and varint of its length, (n, ...) uint8."""
    out = []
    for tag, values, n in ((0x08, sec, a), (0x10, nanos, b)):
        if n:
            shifts = (7 * np.arange(n)).astype(np.uint64)
            varint = ((values.astype(np.uint64)[:, None] >> shifts) & np.uint64(0x7F)).astype(
                np.uint8
            )
            varint[:, : n - 1] |= 0x80
            out += [np.full((len(values), 1), tag, np.uint8), varint]
    return out


@cache
def _stamp_offsets(bodies: tuple[str, ...], probe: tuple[int, int], size: int) -> tuple[int, ...]:
    """Where each transform's stamp lies in `transforms(bodies, probe)`'s payload: the probe
    (the smallest values of its varint lengths) and the largest values of the same lengths
    differ in their first byte; the stamp starts one byte before (its field tag)."""
    a = transforms(bodies, probe).template
    other = (
        (probe[0] << 7) - 1 if probe[0] else 0,
        min((probe[1] << 7) - 1, 999_999_999) if probe[1] else 0,
    )
    starts: list[int] = []
    for i in np.flatnonzero(a != transforms(bodies, other).template).tolist():
        if not starts or i >= starts[-1] + size:
            starts.append(i)
    assert len(starts) == len(bodies), "FrameTransforms layout changed"
    return tuple(s - 1 for s in starts)
