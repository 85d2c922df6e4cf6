"""Fixed layouts (`codec.Template`) of the log's per-step messages, shared by record and analyze.

Value orders:
- BodyState: x y z, qw qx qy qz, vx vy vz, wx wy wz (`BODY_FIELDS`).
- Energy: kinetic potential total.
- Clearance: one distance per surface, in the order of the channel's `surfaces`.
- ContactPoint: the fields of `impactlab.ContactPoint` in number order (`POINT_FIELDS`).
- FrameTransforms: per body tx ty tz, qw qx qy qz.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache

from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms

from impactlab.logs import format as logformat
from impactlab.logs.codec import Template
from impactlab.proto import impactlab_pb2 as pb

BODY_FIELDS = ("x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz", "wx", "wy", "wz")
ENERGY_FIELDS = ("kinetic", "potential", "total")
POINT_FIELDS = tuple(f.name for f in pb.ContactPoint.DESCRIPTOR.fields)


def _set_fields(names: Sequence[str]):
    def setter(msg, values):
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
def clearance(k: int) -> Template:
    """Layout of `impactlab.Clearance` with k distances."""

    def setter(msg, values):
        msg.distance.extend(values)

    return Template.learn(pb.Clearance, setter, k)


@cache
def contact(geom1: str, geom2: str, body1: str, body2: str, points: int) -> Template:
    """Layout of `impactlab.Contact` for one geom pair with `points` contact points."""
    k = len(POINT_FIELDS)

    def make():
        return pb.Contact(geom1=geom1, geom2=geom2, body1=body1, body2=body2)

    def setter(msg, values):
        for i in range(points):
            point = msg.points.add()
            _set_fields(POINT_FIELDS)(point, values[i * k : (i + 1) * k])

    return Template.learn(make, setter, k * points)


@cache
def transforms(bodies: tuple[str, ...]) -> Template:
    """Layout of `foxglove.FrameTransforms`, world -> each body, no per-transform timestamp."""

    def setter(msg, values):
        for i, name in enumerate(bodies):
            tf = msg.transforms.add()
            tf.parent_frame_id = logformat.WORLD_FRAME
            tf.child_frame_id = name
            v = values[7 * i : 7 * i + 7]
            tf.translation.x, tf.translation.y, tf.translation.z = v[0:3]
            tf.rotation.w, tf.rotation.x, tf.rotation.y, tf.rotation.z = v[3:7]

    return Template.learn(FrameTransforms, setter, 7 * len(bodies))
