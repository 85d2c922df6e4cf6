"""Write one run's trajectory to an MCAP file: protobuf channels, metadata and the MJCF.

The file is written under a temporary name beside the target and renamed when complete,
so an interrupted run never leaves a file that looks finished.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mcap
import numpy as np
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from google.protobuf.message import Message
from mcap.writer import Writer
from mcap_protobuf.schema import build_file_descriptor_set

from impactlab import __version__, logformat, messages
from impactlab.proto import impactlab_pb2 as pb
from impactlab.record.chunks import Block, ChunkWriter
from impactlab.record.model import (
    BODY_STATE_SIZE,
    CONTACT_SLOT_SIZE,
    ContactChannel,
    InstrumentedModel,
)
from impactlab.record.scene import scene_update
from impactlab.record.simulate import Trajectory

PARTIAL_SUFFIX = ".partial"
CHUNK_BYTES = 1 << 20  # uncompressed bytes per chunk, as the official writer


@dataclass(frozen=True)
class RunInfo:
    """What the metadata record says about a run besides its trajectory."""

    run_id: str
    experiment: str
    description: str
    source: str
    spec: Mapping[str, Any]
    sweep: Mapping[str, Any]
    spec_hash: str
    log_every: int
    sweep_index: int = 0
    sweep_size: int = 1


def write_log(path: Path, inst: InstrumentedModel, info: RunInfo, traj: Trajectory) -> Path:
    """Write the run to `path` atomically (temporary name, then rename). Returns `path`."""
    tmp = path.with_name(path.name + PARTIAL_SUFFIX)
    try:
        with open(tmp, "wb") as stream:
            _write(stream, inst, info, traj)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


class _Channels:
    """Registers each schema once and each topic once on an MCAP writer."""

    def __init__(self, writer: Writer) -> None:
        self.writer = writer
        self.schemas: dict[str, int] = {}

    def add(self, topic: str, message_type: type[Message], metadata: dict[str, str] | None = None):
        name = message_type.DESCRIPTOR.full_name
        if name not in self.schemas:
            fds = build_file_descriptor_set(message_type)
            self.schemas[name] = self.writer.register_schema(
                name=name, encoding="protobuf", data=fds.SerializeToString()
            )
        return self.writer.register_channel(
            topic=topic,
            message_encoding=logformat.ENCODING,
            schema_id=self.schemas[name],
            metadata=metadata or {},
        )


def _write(stream: Any, inst: InstrumentedModel, info: RunInfo, traj: Trajectory) -> None:
    out = ChunkWriter(
        stream,
        profile=logformat.PROFILE,
        library=f"impactlab {__version__}; mcap-python {mcap.__version__}",
    )
    writer = out.writer
    writer.add_metadata(logformat.RUN_METADATA, run_metadata(inst, info))
    channels = _Channels(writer)
    t_ns, rows = traj.t_ns, traj.sensordata
    scene = channels.add(logformat.SCENE_TOPIC, SceneUpdate)
    bodies = [
        (
            channels.add(
                logformat.BODY_STATE_TOPIC.format(body=b.name), pb.BodyState, {"body": b.name}
            ),
            b,
        )
        for b in inst.bodies
    ]
    pairs = []
    for pair in inst.contacts:
        meta = {"geom1": pair.geom1, "geom2": pair.geom2, "body1": pair.body1, "body2": pair.body2}
        pairs.append((channels.add(pair.topic, pb.Contact, meta), pair))
    energy = channels.add(logformat.ENERGY_TOPIC, pb.Energy)
    tf = channels.add(logformat.TF_TOPIC, FrameTransforms)
    events = channels.add(logformat.EVENTS_TOPIC, Log)
    tf_layout = messages.transforms(tuple(b.name for b in inst.bodies))
    row_bytes = (
        len(bodies) * messages.body_state().size + messages.energy().size + tf_layout.size + 200
    )
    per_chunk = max(1, CHUNK_BYTES // row_bytes)
    scene_payload = np.frombuffer(scene_update(inst).SerializeToString(), np.uint8)[None]
    for lo in range(0, max(len(t_ns), 1), per_chunk):
        t, r = t_ns[lo : lo + per_chunk], rows[lo : lo + per_chunk]
        blocks = [Block(scene, t[:1], scene_payload)] if lo == 0 else []
        for channel_id, body in bodies:
            values = r[:, body.adr : body.adr + BODY_STATE_SIZE]
            blocks.append(Block(channel_id, t, messages.body_state().encode(values)))
        for channel_id, pair in pairs:
            blocks += contact_blocks(channel_id, pair, t, r)
        e = r[:, inst.energy_adr : inst.energy_adr + 2]  # potential, kinetic
        energy_values = np.stack([e[:, 1], e[:, 0], e[:, 0] + e[:, 1]], axis=1)
        blocks.append(Block(energy, t, messages.energy().encode(energy_values)))
        poses = np.concatenate([r[:, b.adr : b.adr + 7] for _, b in bodies], axis=1)
        blocks.append(Block(tf, t, tf_layout.encode(poses)))
        out.write_chunk(blocks)
    end = int(t_ns[-1]) if t_ns.size else 0
    texts = [(Log.INFO, f"{traj.verdict.outcome}: {traj.verdict.reason}")]
    texts += [(Log.WARNING, w) for w in traj.warnings]
    payloads = [_log_message(end, level, text) for level, text in texts]
    out.write_chunk([Block(events, np.full(len(payloads), end, dtype=np.int64), payloads)])
    writer.add_attachment(
        create_time=0,
        log_time=0,
        name=logformat.MODEL_ATTACHMENT,
        media_type="application/xml",
        data=inst.xml.encode(),
    )
    writer.add_metadata(logformat.OUTCOME_METADATA, outcome_metadata(traj))
    out.finish()


def contact_blocks(channel_id: int, pair: ContactChannel, t: np.ndarray, rows: np.ndarray):
    """Blocks of Contact payloads for the rows where the pair touches, one per point count."""
    slots = rows[:, pair.adr : pair.adr + pair.num * CONTACT_SLOT_SIZE]
    slots = slots.reshape(rows.shape[0], pair.num, CONTACT_SLOT_SIZE)
    count = np.minimum(slots[:, 0, 0], pair.num).astype(np.int64)
    force, dist, pos = slots[..., 1:4], slots[..., 4], slots[..., 5:8]
    normal, t1 = slots[..., 8:11], slots[..., 11:14]
    t2 = np.cross(normal, t1)
    world = force[..., 0:1] * normal + force[..., 1:2] * t1 + force[..., 2:3] * t2
    points = np.concatenate(
        [pos, normal, -dist[..., None], force, world], axis=2
    )  # (n, num, 13) in POINT_FIELDS order
    blocks = []
    for k in range(1, pair.num + 1):
        mine = count == k
        if mine.any():
            layout = messages.contact(pair.geom1, pair.geom2, pair.body1, pair.body2, k)
            values = points[mine, :k].reshape(int(mine.sum()), -1)
            blocks.append(Block(channel_id, t[mine], layout.encode(values)))
    return blocks


def run_metadata(inst: InstrumentedModel, info: RunInfo) -> dict[str, str]:
    """The `impactlab.run` metadata record (every value a string)."""
    import mujoco

    model = inst.model
    bodies = [
        {
            "name": b.name,
            "mass": float(model.body_mass[b.body_id]),
            "inertia": [float(x) for x in model.body_inertia[b.body_id]],
            "radius": b.radius,
        }
        for b in inst.bodies
    ]
    plane = [g for g in inst.geoms if g.type == "plane" and g.body == "world"]
    meta = {
        "log_format_version": logformat.LOG_FORMAT_VERSION,
        "impactlab_version": __version__,
        "mujoco_version": mujoco.__version__,
        "experiment": info.experiment,
        "description": info.description,
        "source": info.source,
        "run_id": info.run_id,
        "spec": json.dumps(info.spec, sort_keys=True),
        "sweep": json.dumps(info.sweep, sort_keys=True),
        "sweep_index": str(info.sweep_index),
        "sweep_size": str(info.sweep_size),
        "spec_hash": info.spec_hash,
        "timestep_s": repr(float(model.opt.timestep)),
        "log_every": str(info.log_every),
        "gravity": json.dumps([float(x) for x in model.opt.gravity]),
        "bodies": json.dumps(bodies),
        "plane_z": repr(plane[0].pos[2]) if plane else "",
    }
    assert tuple(meta) == logformat.RUN_KEYS
    return meta


def outcome_metadata(traj: Trajectory) -> dict[str, str]:
    """The `impactlab.outcome` metadata record, written last."""
    meta = {
        "outcome": traj.verdict.outcome,
        "reason": traj.verdict.reason,
        "warnings": json.dumps(traj.warnings),
        "steps": str(traj.verdict.last_step + 1),
    }
    assert tuple(meta) == logformat.OUTCOME_KEYS
    return meta


def _log_message(t_ns: int, level: int, text: str) -> bytes:
    msg = Log(level=level, message=text, name="impactlab")
    msg.timestamp.FromNanoseconds(int(t_ns))
    return msg.SerializeToString()
