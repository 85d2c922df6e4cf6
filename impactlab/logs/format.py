"""What an impactlab log holds: topics, schemas, metadata records and keys (docs/log-format.md).

One MCAP file per run; log_time (= publish_time) is simulation time in integer nanoseconds.
"""

from __future__ import annotations

LOG_FORMAT_VERSION = "3"
READABLE_FORMATS = ("1", "2", "3")  # 1, 2: read for info, diff and replay, not analyzed

BODY_STATE_TOPIC = "/bodies/{body}/state"  # impactlab.BodyState, every logged step
CLEARANCE_TOPIC = "/bodies/{body}/clearance"  # impactlab.Clearance, bodies over a ground
CONTACTS_TOPIC = "/contacts"  # impactlab.Contacts: every contact of a logged step (format 3)
CONTACT_TOPIC_PREFIX = "/contacts/"  # + <geom1>/<geom2>: one pair's contacts (formats 1, 2)
ENERGY_TOPIC = "/energy"  # impactlab.Energy, every logged step
JOINT_ENERGY_TOPIC = "/energy/joints"  # rotor kinetic and spring potential energy
WORK_TOPIC = "/energy/work"  # impactlab.Work: the work of each kind of force so far
IMPACTS_TOPIC = "/impacts"  # impactlab.Impact: each contact episode, at its release
TF_TOPIC = "/tf"  # foxglove.FrameTransforms, every logged step
SCENE_TOPIC = "/scene"  # foxglove.SceneUpdate, once: every visible geom
EVENTS_TOPIC = "/events"  # foxglove.Log, at the end: outcome and warnings
WORLD_FRAME = "world"
NOTHING_MOVES = "nothing moves: every body of the model is welded to the world"
"""The warning of a run whose model has no body that moves (its log has no body channels)."""

BODY_STATE_SCHEMA = "impactlab.BodyState"
CLEARANCE_SCHEMA = "impactlab.Clearance"
CONTACTS_SCHEMA = "impactlab.Contacts"
CONTACT_SCHEMA = "impactlab.Contact"
ENERGY_SCHEMA = "impactlab.Energy"
IMPACT_SCHEMA = "impactlab.Impact"
WORK_SCHEMA = "impactlab.Work"

RUN_METADATA = "impactlab.run"  # right after the header: what the run is
OUTCOME_METADATA = "impactlab.outcome"  # last: how it ended (a cut log lacks it)
SCENE_METADATA = "impactlab.scene"  # the geom table (`impactlab.logs.geoms`)
MODEL_ATTACHMENT = "model.xml"

RUN_KEYS = {  # key: what it holds (`impactlab.logs.metadata` declares each)
    "log_format_version": "the log format's version",
    "impactlab_version": "the recorder's version",
    "mujoco_version": "MuJoCo's version",
    "experiment": "the experiment's name",
    "description": "the experiment's description",
    "source": "the spec file as given",
    "run_id": "the run's id",
    "spec": "JSON object: the resolved spec (its sections objects too)",
    "sweep": "JSON object: {dotted path: value}",
    "sweep_index": "whole number 0 .. 1e+15",
    "sweep_size": "whole number 1 .. 1e+15",
    "spec_hash": "hash of the spec",
    "timestep_s": "number 1e-09 .. 10 s",
    "log_every": "whole number 1 .. 1e+09",
    "gravity": "JSON [gx, gy, gz], each within ±1e+06 m/s^2",
    "bodies": "JSON [{name, mass > 0, inertia [3] >= 0, radius > 0 or null, ...}]",
    "plane_z": "number within ±1e+06 m, or empty: no plane",
    "integrator": "one of Euler, RK4, implicit, implicitfast",
    "ground": "JSON [{name, type, level_m, distance}]",
    "static_potential_J": "number within ±1e+15 J",
    "contact_targets": (
        "JSON [{geom1, geom2, restitution, speed_range_mps: [lo, hi], for an e(v) also "
        "curve_speed_mps: [...], curve_e: [...]}], m/s"
    ),
    "geom_contact": "JSON {solref: [2 numbers], solimp: [3 to 5]}, or empty: the geoms differ",
    "separation_m": "number > 0 m, or empty: no separation rule",
    "half_step_s": "number 0 .. 5 s: dt / 2, or 0 for RK4",
}
OUTCOME_KEYS = {
    "outcome": "one of completed, unstable",
    "reason": "why the run ended",
    "warnings": "JSON list of sentences",
    "steps": "whole number 0 .. 1e+15",
}
RUN_KEYS_ADDED = ("integrator", "ground", "static_potential_J")  # after format 1: may be missing
RUN_KEYS_FORMAT_2 = ("contact_targets", "geom_contact", "separation_m", "half_step_s")
"""What the stages read instead of the spec: in every log from format 2, derived in format 1."""
