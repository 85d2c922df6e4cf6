"""Write one run's log: protobuf channels, metadata and the model, streamed chunk by chunk."""

from __future__ import annotations

import json
import os
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import IO

import mcap
import numpy as np
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from google.protobuf.message import Message
from mcap.writer import Writer
from mcap_protobuf.schema import build_file_descriptor_set

from impactlab.logs import format as logformat
from impactlab.logs import messages
from impactlab.logs.chunks import Block, ChunkWriter
from impactlab.logs.content import LogHeader, LogRows, Outcome
from impactlab.logs.geoms import SCENE_METADATA, STL_MEDIA_TYPE, encode_stl, scene_record
from impactlab.logs.scene import scene_update
from impactlab.proto import impactlab_pb2 as pb
from impactlab.version import __version__

PARTIAL_SUFFIX = ".partial"
CHUNK_BYTES = 1 << 20  # uncompressed bytes per chunk, as the official writer


def partial_path(path: Path) -> Path:
    """The temporary name this thread of this process writes `path` under until it is
    complete: `NAME.THREAD.PID.partial` (`remove_stale_partials` reads the PID)."""
    thread = threading.get_native_id()
    return path.with_name(f"{path.name}.{thread}.{os.getpid()}{PARTIAL_SUFFIX}")


class LogWriter:
    """Writes one run's log as its rows arrive; `finish` makes it complete (see module doc).

    Use as a context manager: leaving it with an exception, or without `finish`, removes
    the temporary file.
    """

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
        header = self.header
        assert self._stream is not None
        self._out = ChunkWriter(
            self._stream,
            profile=logformat.PROFILE,
            library=f"impactlab {__version__}; mcap-python {mcap.__version__}",
        )
        writer = self._out.writer
        writer.add_metadata(logformat.RUN_METADATA, header.run.record())
        writer.add_metadata(
            SCENE_METADATA, scene_record(header.geoms, header.meshes, header.flexes)
        )
        for name, triangles in header.meshes.items():  # first: a cut log still draws the model
            writer.add_attachment(
                create_time=0,
                log_time=0,
                name=name,
                media_type=STL_MEDIA_TYPE,
                data=encode_stl(triangles),
            )
        channels = self._channels = _Channels(writer)
        self._scene = channels.add(logformat.SCENE_TOPIC, SceneUpdate)
        self._bodies = [
            channels.add(
                logformat.BODY_STATE_TOPIC.format(body=b.name), pb.BodyState, {"body": b.name}
            )
            for b in header.run.bodies
        ]
        self._clearance = [
            (
                channels.add(
                    logformat.CLEARANCE_TOPIC.format(body=body),
                    pb.Clearance,
                    {"body": body, "surfaces": json.dumps(list(surfaces))},
                ),
                messages.clearance(len(surfaces)),
            )
            for body, surfaces in header.clearance
        ]
        self._contacts = channels.add(
            logformat.CONTACTS_TOPIC,
            pb.Contacts,
            {key: json.dumps(list(names)) for key, names in header.contact_sides.items()},
        )
        self._energy = channels.add(logformat.ENERGY_TOPIC, pb.Energy)
        self._work = channels.add(logformat.WORK_TOPIC, pb.Work)
        self._joint_energy = (
            channels.add(logformat.JOINT_ENERGY_TOPIC, pb.Energy) if header.joint_energy else None
        )
        self._tf = channels.add(logformat.TF_TOPIC, FrameTransforms)
        self._events = channels.add(logformat.EVENTS_TOPIC, Log)
        self._tf_bodies = tuple(b.name for b in header.run.bodies)
        self._tf_layout = messages.transforms(self._tf_bodies, (1 << 27, 1 << 27))  # its size
        row_bytes = (
            len(self._bodies) * messages.body_state().size
            + messages.energy().size * (2 if header.joint_energy else 1)
            + messages.work().size
            + sum(layout.size for _, layout in self._clearance)
            + self._tf_layout.size
            + 200
        )
        self.rows_per_chunk = max(1, CHUNK_BYTES // row_bytes)
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
        n = len(rows)
        per = self.rows_per_chunk
        end = (n // per) * per if whole_chunks_only else n
        for lo in range(0, end, per):
            self._write_chunk(rows.slice(lo, min(lo + per, end)))
        rest = rows.slice(end, n)
        self._buffer = [rest] if len(rest) else []
        self._buffered = len(rest)

    def _write_chunk(self, rows: LogRows) -> None:
        t = rows.t_ns
        blocks = []
        if self._scene_payload is not None:  # the scene once, with the first row
            blocks.append(Block(self._scene, t[:1], self._scene_payload))
            self._scene_payload = None
        for i, channel_id in enumerate(self._bodies):
            blocks.append(Block(channel_id, t, rows.bodies[:, i], messages.body_state()))
        for (channel_id, layout), values in zip(self._clearance, rows.clearance, strict=True):
            blocks.append(Block(channel_id, t, values, layout))
        row, sides, values = rows.contacts
        blocks.append(Block(self._energy, t, rows.energy, messages.energy()))
        blocks.append(Block(self._work, t, rows.work, messages.work()))
        if self._joint_energy is not None and rows.joint_energy is not None:
            blocks.append(Block(self._joint_energy, t, rows.joint_energy, messages.energy()))
        poses = rows.bodies[:, :, :7].reshape(len(t), -1)
        for rows_tf, payloads in messages.stamped_transforms(self._tf_bodies, t, poses):
            blocks.append(Block(self._tf, t[rows_tf], payloads))
        self._out.write_chunk(blocks)
        if row.size:  # messages of any length: a chunk of their own (the others are dense)
            points = messages.contact_payloads(row, sides, values)
            self._out.write_chunk([Block(self._contacts, t[np.unique(row)], points)])

    def finish(self, outcome: Outcome, impacts: Sequence[pb.Impact] = ()) -> Path:
        """Write the rest, the impacts, the outcome, the model and the summary; rename.

        `impacts`: the run's contact episodes (`/impacts`), in order of `release_ns`.
        """
        try:
            self._flush(whole_chunks_only=False)
            if impacts:
                channel = self._channels.add(logformat.IMPACTS_TOPIC, pb.Impact)
                times = np.array([i.release_ns for i in impacts], dtype=np.int64)
                payloads = [i.SerializeToString() for i in impacts]
                self._out.write_chunk([Block(channel, times, payloads)])
            if self._scene_payload is not None:  # a run with no rows still has its scene
                scene = Block(self._scene, np.zeros(1, np.int64), self._scene_payload)
                self._out.write_chunk([scene])
                self._scene_payload = None
            end = self.last_t_ns
            texts = [(Log.INFO, f"{outcome.outcome}: {outcome.reason}")]
            texts += [(Log.WARNING, w) for w in outcome.warnings]
            payloads = [_log_message(end, level, text) for level, text in texts]
            times = np.full(len(payloads), end, dtype=np.int64)
            self._out.write_chunk([Block(self._events, times, payloads)])
            writer = self._out.writer
            writer.add_attachment(
                create_time=0,
                log_time=0,
                name=logformat.MODEL_ATTACHMENT,
                media_type="application/xml",
                data=self.header.model_xml.encode(),
            )
            for name, media_type, data in self.header.attachments:
                writer.add_attachment(
                    create_time=0, log_time=0, name=name, media_type=media_type, data=data
                )
            writer.add_metadata(logformat.OUTCOME_METADATA, outcome.record())
            self._out.finish()
            assert self._stream is not None
            self._stream.close()
            self._stream = None
            os.replace(self.tmp, self.path)
        except BaseException:
            self.abort()
            raise
        return self.path

    def abort(self) -> None:
        """Close and remove the temporary file (nothing is left behind)."""
        if self._stream is not None:
            self._stream.close()
            self._stream = None
        self.tmp.unlink(missing_ok=True)

    def __enter__(self) -> LogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._stream is not None:
            self.abort()


class _Channels:
    """Registers each schema once and each topic once on an MCAP writer."""

    def __init__(self, writer: Writer) -> None:
        self.writer = writer
        self.schemas: dict[str, int] = {}

    def add(
        self, topic: str, message_type: type[Message], metadata: dict[str, str] | None = None
    ) -> int:
        name = message_type.DESCRIPTOR.full_name
        if name not in self.schemas:
            self.schemas[name] = self.writer.register_schema(
                name=name, encoding="protobuf", data=_schema_data(message_type)
            )
        return self.writer.register_channel(
            topic=topic,
            message_encoding=logformat.ENCODING,
            schema_id=self.schemas[name],
            metadata=metadata or {},
        )


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


def remove_partials_of(folder: Path, pid: int) -> None:
    """Remove the temporary files process `pid`, which no longer runs, left in `folder`."""
    for tmp in folder.glob(f"*.{pid}{PARTIAL_SUFFIX}"):
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
