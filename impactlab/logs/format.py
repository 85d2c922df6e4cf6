"""What an impactlab log holds: topics, schema names and metadata keys, shared by every stage.

One MCAP file per run. log_time (= publish_time) is simulation time in integer nanoseconds.

| topic                       | schema                  | when                                |
|-----------------------------|-------------------------|-------------------------------------|
| /bodies/<body>/state        | impactlab.BodyState     | every logged step                   |
| /bodies/<body>/clearance    | impactlab.Clearance     | every logged step (bodies with a    |
|                             |                         | ground surface to measure against)  |
| /contacts                   | impactlab.Contacts      | every logged step with a contact    |
| /impacts                    | impactlab.Impact        | each contact episode, at the end    |
| /energy                     | impactlab.Energy        | every logged step                   |
| /energy/work                | impactlab.Work          | every logged step                   |
| /energy/joints              | impactlab.Energy        | every logged step (models with      |
|                             |                         | rotor inertia or springs)           |
| /tf                         | foxglove.FrameTransforms| every logged step (each transform   |
|                             |                         | stamped with the log time)          |
| /scene                      | foxglove.SceneUpdate    | once, at t = 0: every visible geom  |
| /events                     | foxglove.Log            | at the end (outcome, warnings)      |

Metadata records: `impactlab.run` right after the header (what the run is: spec, sweep,
versions, bodies; and since format 2 what the stages read instead of the spec, declared in
`impactlab.logs.contract`), `impactlab.outcome` at the end (how it ended), so a truncated log still
says what it was and, by lacking the outcome, that it is incomplete. Attachment `model.xml`:
the compiled MJCF, whose keyframe `initial` holds the initial state (a user's model: its text
with includes inlined); `model.mjb` too for a model that reads mesh or texture files. What
draws the model without MuJoCo: the metadata record `impactlab.scene` (the geom table) and
the STL attachments `meshes/<mesh>.stl`, `hfields/<hfield>.stl` (`impactlab.logs.geoms`,
added to format 1).
"""

from __future__ import annotations

LOG_FORMAT_VERSION = "3"
READABLE_FORMATS = ("1", "2", "3")  # 1, 2: read for info, diff and replay, not analyzed
PROFILE = ""  # no MCAP well-known profile fits protobuf logs of a simulator
ENCODING = "protobuf"

BODY_STATE_TOPIC = "/bodies/{body}/state"
CLEARANCE_TOPIC = "/bodies/{body}/clearance"
CONTACTS_TOPIC = "/contacts"  # every contact point of a logged step (format 3 on)
CONTACTS_SCHEMA = "impactlab.Contacts"
CONTACT_TOPIC_PREFIX = "/contacts/"  # + <geom1>/<geom2>: one pair's contacts (formats 1, 2)
ENERGY_TOPIC = "/energy"
JOINT_ENERGY_TOPIC = "/energy/joints"  # the joints' rotor kinetic and spring potential energy
TF_TOPIC = "/tf"
SCENE_TOPIC = "/scene"
EVENTS_TOPIC = "/events"
WORLD_FRAME = "world"

BODY_STATE_SCHEMA = "impactlab.BodyState"
CLEARANCE_SCHEMA = "impactlab.Clearance"
CONTACT_SCHEMA = "impactlab.Contact"
IMPACT_SCHEMA = "impactlab.Impact"
IMPACTS_TOPIC = "/impacts"  # each contact episode of a pair of parties (record.episodes)
WORK_SCHEMA = "impactlab.Work"
WORK_TOPIC = "/energy/work"  # the work of each kind of force so far (record.budget)
ENERGY_SCHEMA = "impactlab.Energy"

RUN_METADATA = "impactlab.run"
OUTCOME_METADATA = "impactlab.outcome"
MODEL_ATTACHMENT = "model.xml"
SCENE_METADATA = "impactlab.scene"  # the geom table (impactlab.logs.geoms), added to format 1

# keys of the run metadata record
RUN_KEYS = (
    "log_format_version",
    "impactlab_version",
    "mujoco_version",
    "experiment",
    "description",
    "source",
    "run_id",
    "spec",  # JSON: the resolved spec document (or the MJCF path and duration)
    "sweep",  # JSON: {dotted path: value} of this run's sweep point
    "sweep_index",  # this run's place in the sweep grid, 0-based
    "sweep_size",  # runs in the sweep grid (1 without a sweep)
    "spec_hash",
    "timestep_s",
    "log_every",
    "gravity",  # JSON [gx, gy, gz], m/s^2
    "bodies",  # JSON [{name, mass, inertia, radius, shape, rest_height_m, geoms}], kg, kg m^2, m
    "plane_z",  # height of the plane in m, or "" when there is none
    "integrator",  # MuJoCo's integrator (Euler, RK4, implicit, implicitfast)
    "ground",  # JSON [{name, type, level_m, distance}]: the static geoms bodies can land on
    "static_potential_J",  # MuJoCo's potential energy of the static bodies (a constant), J
    "contact_targets",  # JSON [{geom1, geom2, restitution, speed_range_mps}]: calibrated pairs
    "geom_contact",  # JSON {solref, solimp} every geom shares, or "" when they differ
    "separation_m",  # the separation stop rule in m (a collision), or "" when there is none
    "half_step_s",  # the integrator's half step: dt / 2 (semi-implicit), 0 (RK4), s
)
# keys added after format version 1 was first written; older logs lack them (compatible)
RUN_KEYS_ADDED = ("integrator", "ground", "static_potential_J")
# keys format 2 added: what the analysis reads instead of the spec (`impactlab.logs.contract`);
# every format-2 log has them, and a format-1 log gets them derived from its spec
RUN_KEYS_FORMAT_2 = ("contact_targets", "geom_contact", "separation_m", "half_step_s")
# keys of the outcome metadata record
OUTCOME_KEYS = (
    "outcome",  # completed | unstable
    "reason",
    "warnings",  # JSON list of sentences
    "steps",  # number of simulated steps
)
