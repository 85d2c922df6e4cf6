"""Write one run's log: protobuf channels, metadata and the model, streamed chunk by chunk."""

from __future__ import annotations

import contextlib
import json
import os
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import mcap
import numpy as np
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from google.protobuf.message import Message
from mcap_protobuf.schema import build_file_descriptor_set

from impactlab.logs import format as logformat
from impactlab.logs import messages
from impactlab.logs.chunks import Block, ChunkWriter
from impactlab.logs.geoms import (
    SCENE_METADATA,
    STL_MEDIA_TYPE,
    FlexShape,
    GeomShape,
    encode_stl,
    scene_record,
    scene_update,
)
from impactlab.logs.metadata import Outcome, RunMeta
from impactlab.proto import impactlab_pb2 as pb
from impactlab.version import __version__

PARTIAL_SUFFIX = ".partial"
CHUNK_BYTES = 1 << 20  # uncompressed bytes per chunk, as the official writer
MIN_CHUNK_ROWS = 16  # a model of thousands of bodies: chunks of 16 steps, not of one


@dataclass(frozen=True)
class LogHeader:
    """Everything a log holds besides its rows: the run, its scene and its model.

    `clearance`: per body with a clearance channel, the surfaces its distances are measured
    to, in value order; `meshes`: the triangles (m, 3, 3) of the geoms' meshes by attachment
    name; `contact_sides`: the /contacts channel's metadata, what a point's sides refer to:
    `geoms` (every geom's name, by id), `bodies` (the party of each geom), `flexes` (by id).
    """

    run: RunMeta
    geoms: Sequence[GeomShape]
    model_xml: str
    clearance: Sequence[tuple[str, tuple[str, ...]]] = ()
    joint_energy: bool = False  # whether rows carry `joint_energy` (`/energy/joints`)
    attachments: Sequence[tuple[str, str, bytes]] = ()  # more files: name, media type, data
    meshes: Mapping[str, np.ndarray] = field(default_factory=dict)
    flexes: Sequence[FlexShape] = ()
    contact_sides: Mapping[str, Sequence[str]] = field(default_factory=dict)


@dataclass
class LogRows:
    """Consecutive logged rows of a run: times `t_ns` (n,) int ns; `bodies` (n, nbody, 13) in
    `RunMeta.bodies` order and `messages.BODY_FIELDS` order; `energy` (n, 3) J; `work` (n, k)
    J since the start, `messages.WORK_FIELDS`; `contacts`, one entry per point: its row (m,)
    (ascending), sides (m, 2) (a geom id, or -1 - a flex id) and values (m, 13) in
    `POINT_FIELDS` order;
    `clearance` (n, m) m, the distances of every body of `LogHeader.clearance` side by side, in
    its order (each body's surfaces in theirs); `joint_energy` (n, 3) J or None."""

    t_ns: np.ndarray
    bodies: np.ndarray
    energy: np.ndarray
    work: np.ndarray
    contacts: tuple[np.ndarray, np.ndarray, np.ndarray]
    clearance: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))
    joint_energy: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.t_ns.size)

    def slice(self, lo: int, hi: int) -> LogRows:
        """Rows lo .. hi - 1 (views: the contacts' rows ascend)."""
        row, sides, values = self.contacts
        a, b = np.searchsorted(row, (lo, hi)).tolist()
        return LogRows(
            self.t_ns[lo:hi],
            self.bodies[lo:hi],
            self.energy[lo:hi],
            self.work[lo:hi],
            (row[a:b] - lo, sides[a:b], values[a:b]),
            self.clearance[lo:hi],
            None if self.joint_energy is None else self.joint_energy[lo:hi],
        )

    @staticmethod
    def concat(parts: Sequence[LogRows]) -> LogRows:
        """The rows of `parts`, one after the other."""
        if len(parts) == 1:
            return parts[0]
        offsets = np.cumsum([0] + [len(p) for p in parts[:-1]])
        cat = np.concatenate
        return LogRows(
            cat([p.t_ns for p in parts]),
            cat([p.bodies for p in parts]),
            cat([p.energy for p in parts]),
            cat([p.work for p in parts]),
            (
                cat([p.contacts[0] + o for p, o in zip(parts, offsets, strict=True)]),
                cat([p.contacts[1] for p in parts]),
                cat([p.contacts[2] for p in parts]),
            ),
            cat([p.clearance for p in parts]),
            None if parts[0].joint_energy is None else cat([p.joint_energy for p in parts]),
        )


def partial_path(path: Path) -> Path:
    """The temporary name this thread of this process writes `path` under until it is
    complete: `NAME.THREAD.PID.partial` (`remove_stale_partials` reads the PID)."""
    thread = threading.get_native_id()
    return path.with_name(f"{path.name}.{thread}.{os.getpid()}{PARTIAL_SUFFIX}")


class LogWriter:
    """Writes one run's log as its rows arrive; `finish` makes it complete. Leaving it as a
    context manager with an exception, or without `finish`, removes the temporary file."""

    def __init__(self, path: Path, header: LogHeader) -> None:
        self.path = Path(path)
        self.tmp = partial_path(self.path)
        self.header = header
        self._stream: IO[bytes] | None = open(self.tmp, "wb")  # noqa: SIM115 (closed by finish)
        try:
            self._start()
        except BaseException:
            self.abort()
            raise

    def _start(self) -> None:
        header, bodies = self.header, tuple(b.name for b in self.header.run.bodies)
        assert self._stream is not None
        out = self._out = ChunkWriter(
            self._stream, library=f"impactlab {__version__}; mcap-python {mcap.__version__}"
        )

        def add(topic: str, kind: type[Message], metadata: Mapping[str, str] | None = None) -> int:
            name = kind.DESCRIPTOR.full_name
            return out.channel(topic, name, _schema_data(kind), dict(metadata or {}))

        # every channel before the metadata, which writes them out (`ChunkWriter`)
        self._scene = add(logformat.SCENE_TOPIC, SceneUpdate)
        self._bodies = [
            add(logformat.BODY_STATE_TOPIC.format(body=b), pb.BodyState, {"body": b})
            for b in bodies
        ]
        self._clearance = [
            add(
                logformat.CLEARANCE_TOPIC.format(body=b),
                pb.Clearance,
                {"body": b, "surfaces": json.dumps(list(surfaces))},
            )
            for b, surfaces in header.clearance
        ]
        sides = {key: json.dumps(list(names)) for key, names in header.contact_sides.items()}
        self._contacts = add(logformat.CONTACTS_TOPIC, pb.Contacts, sides)
        self._energy = add(logformat.ENERGY_TOPIC, pb.Energy)
        self._work = add(logformat.WORK_TOPIC, pb.Work)
        self._joints = add(logformat.JOINT_ENERGY_TOPIC, pb.Energy) if header.joint_energy else None
        self._tf = add(logformat.TF_TOPIC, FrameTransforms)
        self._impacts = add(logformat.IMPACTS_TOPIC, pb.Impact)
        self._events = add(logformat.EVENTS_TOPIC, Log)
        writer = out.writer
        writer.add_metadata(logformat.RUN_METADATA, header.run.record())
        writer.add_metadata(
            SCENE_METADATA, scene_record(header.geoms, header.meshes, header.flexes)
        )
        for name, triangles in header.meshes.items():  # first: a cut log still draws the model
            out.attach(name, STL_MEDIA_TYPE, encode_stl(triangles))
        self._tf_bodies = bodies
        # per number of surfaces: the channels, and their columns of `LogRows.clearance`
        first = np.cumsum([0] + [len(s) for _, s in header.clearance])
        layouts: dict[int, list[int]] = {}
        for i, (_, surfaces) in enumerate(header.clearance):
            layouts.setdefault(len(surfaces), []).append(i)
        self._clearance_layouts = {
            width: (np.array(self._clearance)[at], (first[at, None] + np.arange(width)).ravel())
            for width, at in layouts.items()
        }
        row_bytes = (
            len(bodies) * messages.body_state().size
            + messages.energy().size * (2 if header.joint_energy else 1)
            + messages.work().size
            + sum(messages.clearance(len(s)).size for _, s in header.clearance)
            + messages.transforms(bodies, (1 << 27, 1 << 27)).size  # its largest stamp
            + 200
        )
        self.rows_per_chunk = max(MIN_CHUNK_ROWS, CHUNK_BYTES // row_bytes)
        scene = scene_update(header.geoms, header.meshes).SerializeToString()
        self._scene_payload: np.ndarray | None = np.frombuffer(scene, np.uint8)[None]
        self._buffer: list[LogRows] = []
        self._buffered = 0
        self.last_t_ns = 0

    def write(self, rows: LogRows) -> None:
        """Add rows (in time order); whole chunks are written as soon as they are full."""
        if not len(rows):
            return
        self._buffer.append(rows)
        self._buffered += len(rows)
        self.last_t_ns = int(rows.t_ns[-1])
        if self._buffered >= self.rows_per_chunk:
            self._flush(whole_chunks_only=True)

    def _flush(self, *, whole_chunks_only: bool) -> None:
        if not self._buffer:
            return
        rows = LogRows.concat(self._buffer)
        n, per = len(rows), self.rows_per_chunk
        end = (n // per) * per if whole_chunks_only else n
        for lo in range(0, end, per):
            self._write_chunk(rows.slice(lo, min(lo + per, end)))
        rest = rows.slice(end, n)
        self._buffer, self._buffered = ([rest] if len(rest) else []), len(rest)

    def _write_chunk(self, rows: LogRows) -> None:
        t = rows.t_ns
        blocks = []
        if self._scene_payload is not None:  # the scene once, with the first row
            blocks.append(Block(self._scene, t[:1], self._scene_payload))
            self._scene_payload = None
        if self._bodies:  # one block for every body: its cost does not grow with them
            states = messages.body_state().encode(rows.bodies.reshape(-1, rows.bodies.shape[2]))
            blocks.append(
                Block(np.array(self._bodies), t, states.reshape(len(t), len(self._bodies), -1))
            )
        for width, (ids, columns) in self._clearance_layouts.items():  # a block per layout
            values = rows.clearance[:, columns].reshape(-1, width)
            payloads = messages.clearance(width).encode(values)
            blocks.append(Block(ids, t, payloads.reshape(len(t), len(ids), -1)))
        blocks.append(Block(self._energy, t, messages.energy().encode(rows.energy)))
        blocks.append(Block(self._work, t, messages.work().encode(rows.work)))
        if self._joints is not None and rows.joint_energy is not None:
            blocks.append(Block(self._joints, t, messages.energy().encode(rows.joint_energy)))
        poses = rows.bodies[:, :, :7].reshape(len(t), -1)
        for at, payloads in messages.stamped_transforms(self._tf_bodies, t, poses):
            blocks.append(Block(self._tf, t[at], payloads))
        self._out.write_chunk(blocks)
        row, sides, values = rows.contacts
        if row.size:  # a chunk of their own: a block per number of points
            groups = messages.contact_payloads(row, sides, values)
            self._out.write_chunk([Block(self._contacts, t[at], p) for at, p in groups])

    def finish(self, outcome: Outcome, impacts: Sequence[pb.Impact] = ()) -> Path:
        """Write the rest, the impacts (`/impacts`: the run's contact episodes, in order of
        `release_ns`), the events, the model, the outcome and the summary; rename."""
        try:
            self._flush(whole_chunks_only=False)
            times = np.array([i.release_ns for i in impacts], dtype=np.int64)
            self._out.write_chunk(
                [Block(self._impacts, times, [i.SerializeToString() for i in impacts])]
            )
            if self._scene_payload is not None:  # a run with no rows still has its scene
                self._out.write_chunk(
                    [Block(self._scene, np.zeros(1, np.int64), self._scene_payload)]
                )
            texts = [(Log.INFO, f"{outcome.outcome}: {outcome.reason}")]
            texts += [(Log.WARNING, w) for w in outcome.warnings]
            events = [_log_message(self.last_t_ns, level, text) for level, text in texts]
            self._out.write_chunk(
                [Block(self._events, np.full(len(events), self.last_t_ns), events)]
            )
            writer = self._out.writer
            model = self.header.model_xml.encode()
            self._out.attach(logformat.MODEL_ATTACHMENT, "application/xml", model)
            for name, media_type, data in self.header.attachments:
                self._out.attach(name, media_type, data)
            writer.add_metadata(logformat.OUTCOME_METADATA, outcome.record())
            writer.finish()  # type: ignore[no-untyped-call]  # mcap: finish() has no hints
            self._out.close()
            assert self._stream is not None
            self._stream.close()
            self._stream = None
            os.replace(self.tmp, self.path)
        except BaseException:
            self.abort()
            raise
        return self.path

    def abort(self) -> None:
        """Close and remove the temporary file (nothing is left behind, also when closing
        fails: a full disk refuses what was still buffered)."""
        if hasattr(self, "_out"):  # the chunk being written, before the file is closed
            self._out.close()
        if self._stream is not None:
            with contextlib.suppress(OSError):
                self._stream.close()
            self._stream = None
        self.tmp.unlink(missing_ok=True)

    def __enter__(self) -> LogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._stream is not None:
            self.abort()


_SCHEMA_DATA: dict[str, bytes] = {}  # message type's full name -> its FileDescriptorSet


def _schema_data(message_type: type[Message]) -> bytes:
    """The serialised FileDescriptorSet of a message type (built once per process)."""
    name = message_type.DESCRIPTOR.full_name
    if name not in _SCHEMA_DATA:
        _SCHEMA_DATA[name] = build_file_descriptor_set(message_type).SerializeToString()
    return _SCHEMA_DATA[name]


def _log_message(t_ns: int, level: Log.Level.ValueType, text: str) -> bytes:
    msg = Log(level=level, message=text, name="impactlab")
    msg.timestamp.FromNanoseconds(int(t_ns))
    payload: bytes = msg.SerializeToString()
    return payload


def remove_stale_partials(path: Path) -> None:
    """Remove temporary files of `path` left by processes that no longer run (SIGKILL).

    Temporary files of live processes (a concurrent job writing the same run, another thread
    of this process) are kept.
    """
    for tmp in path.parent.glob(f"{path.name}.*{PARTIAL_SUFFIX}"):
        pid = tmp.name.removesuffix(PARTIAL_SUFFIX).rpartition(".")[2]
        if pid.isdigit() and (int(pid) == os.getpid() or _alive(int(pid))):
            continue
        tmp.unlink(missing_ok=True)


def _alive(pid: int) -> bool:
    """Whether process `pid` runs: a dead one that is not reaped yet (a zombie, whose parent
    was killed too) does not."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            state = stat.read().rpartition(b")")[2].split()[0]  # after the command's name
    except (OSError, IndexError):
        return True  # no /proc (not Linux): alive, as it answered
    return state not in (b"Z", b"X")
