"""Write one run's trajectory to an MCAP file: protobuf channels, metadata and the MJCF.

The file is written under a temporary name beside the target and renamed when complete,
so an interrupted run never leaves a file that looks finished.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mcap
import numpy as np
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from google.protobuf.message import Message
from mcap.writer import Writer
from mcap_protobuf.schema import build_file_descriptor_set

from impactlab import __version__, logformat
from impactlab.proto import impactlab_pb2 as pb
from impactlab.record.model import CONTACT_SLOT_SIZE, InstrumentedModel
from impactlab.record.scene import scene_update
from impactlab.record.simulate import Trajectory

PARTIAL_SUFFIX = ".partial"


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
    writer = Writer(stream)
    writer.start(
        profile=logformat.PROFILE,
        library=f"impactlab {__version__}; mcap-python {mcap.__version__}",
    )
    writer.add_metadata(logformat.RUN_METADATA, run_metadata(inst, info))
    channels = _Channels(writer)
    t_ns = traj.t_ns
    rows = traj.sensordata

    def emit(channel: int, times: np.ndarray, payloads: Sequence[bytes]) -> None:
        for t, data in zip(times.tolist(), payloads, strict=True):
            writer.add_message(channel, log_time=t, data=data, publish_time=t)

    scene = channels.add(logformat.SCENE_TOPIC, SceneUpdate)
    emit(scene, t_ns[:1], [scene_update(inst).SerializeToString()])
    for body in inst.bodies:
        topic = logformat.BODY_STATE_TOPIC.format(body=body.name)
        ch = channels.add(topic, pb.BodyState, {"body": body.name})
        emit(ch, t_ns, encode_body_states(rows[:, body.adr : body.adr + 13]))
    for pair in inst.contacts:
        meta = {"geom1": pair.geom1, "geom2": pair.geom2, "body1": pair.body1, "body2": pair.body2}
        ch = channels.add(pair.topic, pb.Contact, meta)
        slots = rows[:, pair.adr : pair.adr + pair.num * CONTACT_SLOT_SIZE]
        found = slots[:, 0] > 0
        emit(ch, t_ns[found], encode_contacts(pair_names=meta, slots=slots[found], num=pair.num))
    ch = channels.add(logformat.ENERGY_TOPIC, pb.Energy)
    energy = rows[:, inst.energy_adr : inst.energy_adr + 2]
    emit(ch, t_ns, encode_energy(energy))
    ch = channels.add(logformat.TF_TOPIC, FrameTransforms)
    emit(ch, t_ns, encode_transforms(inst, rows, t_ns))
    ch = channels.add(logformat.EVENTS_TOPIC, Log)
    end = t_ns[-1:] if t_ns.size else np.zeros(1, dtype=np.int64)
    events = [_log_message(end[0], Log.INFO, f"{traj.verdict.outcome}: {traj.verdict.reason}")]
    events += [_log_message(end[0], Log.WARNING, w) for w in traj.warnings]
    emit(ch, np.repeat(end, len(events)), events)
    writer.add_attachment(
        create_time=0,
        log_time=0,
        name=logformat.MODEL_ATTACHMENT,
        media_type="application/xml",
        data=inst.xml.encode(),
    )
    writer.add_metadata(logformat.OUTCOME_METADATA, outcome_metadata(traj))
    writer.finish()


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


def encode_body_states(values: np.ndarray) -> list[bytes]:
    """BodyState payloads from rows of (pos 3, quat wxyz 4, linvel 3, angvel 3), (n, 13)."""
    names = ("x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz")
    return [
        pb.BodyState(**dict(zip(names, row, strict=True))).SerializeToString()
        for row in values.tolist()
    ]


def encode_energy(values: np.ndarray) -> list[bytes]:
    """Energy payloads from rows of (potential, kinetic) in J, (n, 2)."""
    return [
        pb.Energy(kinetic=k, potential=p, total=p + k).SerializeToString()
        for p, k in values.tolist()
    ]


def encode_contacts(*, pair_names: Mapping[str, str], slots: np.ndarray, num: int) -> list[bytes]:
    """Contact payloads from contact-sensor slots, (n, num * 14) with found > 0 in slot 0."""
    out = []
    for row in slots.reshape(slots.shape[0], num, CONTACT_SLOT_SIZE):
        count = min(int(row[0, 0]), num)
        points = []
        for slot in row[:count]:
            force, dist, pos, normal, t1 = slot[1:4], slot[4], slot[5:8], slot[8:11], slot[11:14]
            t2 = np.cross(normal, t1)
            world = force[0] * normal + force[1] * t1 + force[2] * t2
            points.append(
                pb.ContactPoint(
                    x=pos[0],
                    y=pos[1],
                    z=pos[2],
                    nx=normal[0],
                    ny=normal[1],
                    nz=normal[2],
                    penetration=-dist,
                    normal_force=force[0],
                    friction_force_t1=force[1],
                    friction_force_t2=force[2],
                    fx=world[0],
                    fy=world[1],
                    fz=world[2],
                )
            )
        out.append(pb.Contact(**pair_names, points=points).SerializeToString())
    return out


def encode_transforms(inst: InstrumentedModel, rows: np.ndarray, t_ns: np.ndarray) -> list[bytes]:
    """foxglove.FrameTransforms payloads (world -> each free body) for every row."""
    out = []
    for i, t in enumerate(t_ns.tolist()):
        msg = FrameTransforms()
        for body in inst.bodies:
            pos, quat = rows[i, body.adr : body.adr + 3], rows[i, body.adr + 3 : body.adr + 7]
            tf: FrameTransform = msg.transforms.add()
            tf.timestamp.FromNanoseconds(t)
            tf.parent_frame_id = logformat.WORLD_FRAME
            tf.child_frame_id = body.name
            tf.translation.x, tf.translation.y, tf.translation.z = pos.tolist()
            tf.rotation.w, tf.rotation.x, tf.rotation.y, tf.rotation.z = quat.tolist()
        out.append(msg.SerializeToString())
    return out
