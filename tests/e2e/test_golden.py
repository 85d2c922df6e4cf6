"""Golden logs: today's recorder reproduces them, an independent reader agrees with load.py, the
current schema still reads them, and analyzing them reproduces the golden analysis tables.

The goldens were recorded on one machine and are checked on whatever machine runs the tests:
MuJoCo and numpy's vectorised kernels (the contact designer's exp and log) may round the last
bit differently on another CPU, so nothing computed is compared bit for bit. A recording
agrees with its golden log when every decoded value of every channel load.py decodes (body
states, contact points, energy, events) agrees to 12 significant digits of its channel's scale
(`impactlab.golden.golden_tolerance`), message times and counts are equal, every metadata key
agrees (numbers in it to 12 digits) except `source` (the spec's path, which depends on the
checkout) and `impactlab_version` (a release with the same physics keeps its golden logs), and
the attached model.xml agrees as text, its numbers to 12 digits. `mujoco_version` is compared:
a new MuJoCo pin changes the numbers, and the goldens are then regenerated on purpose
(`python -m impactlab.golden`). The file bytes themselves are not compared (chunking and
compression may change freely), nor are /tf and /scene (derived from the body states and the
model). The smallest physical change the tests make (one contact damping) moves values by
about 1e-3 of their scale, nine orders of magnitude above the tolerance.

The analysis tables are compared with rtol 1e-9, atol 1e-12 (`TABLE_RTOL`, `TABLE_ATOL`).
Where the official reader and load.py decode the same file, values are compared exactly:
both decode the same bytes, no arithmetic is involved.
"""

from __future__ import annotations

import json
import re
from collections import Counter
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from google.protobuf import descriptor_pb2
from google.protobuf.unknown_fields import UnknownFieldSet
from mcap.reader import make_reader
from mcap.writer import Writer
from mcap_copy import register_like
from mcap_protobuf.decoder import DecoderFactory
from polars.testing import assert_frame_equal

from impactlab.golden import (
    GOLDENS,
    LOGS_DIR,
    RESULT_TABLES,
    RESULTS_DIR,
    Golden,
    analysis_tables,
    compare_golden,
    record_golden,
)
from impactlab.logs import format as logformat
from impactlab.logs.load import load_log
from impactlab.logs.messages import BODY_FIELDS, ENERGY_FIELDS, POINT_FIELDS
from impactlab.proto import impactlab_pb2 as pb
from impactlab.tools.diff import EXACT, diff_logs, fmt_t

IDS = [g.name for g in GOLDENS]
# every golden log; drop_bounces, the largest (1 to 2.5 s a test), in the slow tier only
READ = [
    pytest.param(g, id=g.name, marks=[pytest.mark.slow] if g.name == "drop_bounces" else [])
    for g in GOLDENS
]
CURRENT_SCHEMAS = {
    logformat.BODY_STATE_SCHEMA: pb.BodyState,
    logformat.CONTACTS_SCHEMA: pb.Contacts,
    logformat.ENERGY_SCHEMA: pb.Energy,
    logformat.CLEARANCE_SCHEMA: pb.Clearance,
}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> dict[str, Path]:
    """Every golden spec recorded today, by golden name."""
    out = tmp_path_factory.mktemp("golden-now")
    return {g.name: record_golden(g, out) for g in GOLDENS}


def test_golden_logs_exist_and_are_small():
    sizes = {g.name: g.log_path.stat().st_size for g in GOLDENS}
    assert sum(sizes.values()) < 3_000_000, sizes
    assert {p.name for p in LOGS_DIR.glob("*.mcap")} == {f"{g.name}.mcap" for g in GOLDENS}


@pytest.mark.slow
@pytest.mark.parametrize("golden", GOLDENS, ids=IDS)
def test_recording_reproduces_the_golden_log(golden: Golden, recorded):
    diff = compare_golden(golden.log_path, recorded[golden.name])
    assert diff.equal, (
        f"recording {golden.spec_path.name} today differs from its golden log; if intended, "
        f"regenerate with `python -m impactlab.golden`:\n{diff.report()}"
    )
    assert sum(c.messages_a for c in diff.channels) > 100  # it compared something


def read_official(path: Path):
    """Summary, metadata and every decoded message, with the official reader only."""
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        messages = [(ch.topic, m.log_time, msg) for _, ch, m, msg in reader.iter_decoded_messages()]
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    return summary, messages, meta


@pytest.mark.parametrize("golden", READ)
def test_official_reader_agrees_with_load(golden: Golden):
    summary, messages, meta = read_official(golden.log_path)
    counts = Counter(topic for topic, _, _ in messages)
    stats = summary.statistics
    assert stats.message_count == len(messages)
    by_topic = {summary.channels[i].topic: n for i, n in stats.channel_message_counts.items()}
    assert by_topic == dict(counts)
    run = load_log(golden.log_path)
    assert not run.partial, run.problems
    assert run.meta == meta[logformat.RUN_METADATA] | meta[logformat.OUTCOME_METADATA]
    for body, frame in run.bodies.items():
        topic = logformat.BODY_STATE_TOPIC.format(body=body)
        states = [(t, m) for tp, t, m in messages if tp == topic]
        assert frame.height == counts[topic] == counts[logformat.ENERGY_TOPIC]
        assert frame["t_ns"].to_list() == [t for t, _ in states]
        for name in BODY_FIELDS:
            assert frame[name].to_list() == [getattr(m, name) for _, m in states], (topic, name)
    energy = [m for tp, _, m in messages if tp == logformat.ENERGY_TOPIC]
    for name in ENERGY_FIELDS:
        assert run.energy[name].to_list() == [getattr(m, name) for m in energy]
    contacts = [(t, m) for tp, t, m in messages if tp == logformat.CONTACTS_TOPIC]
    assert contacts, "every golden run has contacts"
    channel = next(c for c in summary.channels.values() if c.topic == logformat.CONTACTS_TOPIC)
    geoms = json.loads(channel.metadata["geoms"])
    rows = [
        (t, geoms[p.geom1], geoms[p.geom2], i, p)
        for t, m in contacts
        for i, p in enumerate(m.points)
    ]
    frame = run.contacts
    assert frame.height == len(rows)
    assert frame.select("t_ns", "geom1", "geom2", "point").rows() == [r[:4] for r in rows]
    for name in POINT_FIELDS:
        assert frame[name].to_list() == [getattr(r[4], name) for r in rows], name
    assert run.contacts["t_ns"].n_unique() == counts[logformat.CONTACTS_TOPIC]
    impacts = [(t, m) for tp, t, m in messages if tp == logformat.IMPACTS_TOPIC]
    assert impacts, "every golden run has contacts, each an episode"
    frame = run.impacts
    assert frame["release_ns"].to_list() == [t for t, _ in impacts]
    for name, column in [
        ("onset_ns", "onset_ns"),
        ("side1", "side1"),
        ("side2", "side2"),
        ("work_compression", "work_compression_J"),
        ("work_restitution", "work_restitution_J"),
        ("v_in", "v_in_mps"),
        ("v_out", "v_out_mps"),
        ("open", "open"),
    ]:
        assert frame[column].to_list() == [getattr(m, name) for _, m in impacts], name
    work = [m for tp, _, m in messages if tp == logformat.WORK_TOPIC]
    assert run.work["contact_normal"].to_list() == [m.contact_normal for m in work]
    events = [m.message for tp, _, m in messages if tp == logformat.EVENTS_TOPIC]
    assert run.events["message"].to_list() == events
    assert events[0] == f"completed: {run.meta['reason']}"


def _logged_descriptor(schema_data: bytes, name: str) -> descriptor_pb2.DescriptorProto:
    fds = descriptor_pb2.FileDescriptorSet.FromString(schema_data)
    package, _, message = name.rpartition(".")
    for file in fds.file:
        if file.package == package:
            for msg in file.message_type:
                if msg.name == message:
                    return msg
    raise AssertionError(f"schema {name} not in its own FileDescriptorSet")


def _fields(proto: descriptor_pb2.DescriptorProto) -> dict[str, tuple[int, int, int, str]]:
    return {f.name: (f.number, f.type, f.label, f.type_name) for f in proto.field}


@pytest.mark.parametrize("golden", READ)
def test_golden_logs_still_decode_with_the_current_schema(golden: Golden):
    """A schema change that breaks reading existing logs fails here: see docs/log-format.md."""
    summary, _, meta = read_official(golden.log_path)
    assert meta[logformat.RUN_METADATA]["log_format_version"] == logformat.LOG_FORMAT_VERSION
    logged = {s.name: s for s in summary.schemas.values()}
    assert set(CURRENT_SCHEMAS) - {logformat.CLEARANCE_SCHEMA} <= set(logged)
    if any(g.type == "plane" for g in load_log(golden.log_path).surfaces or []):
        assert logformat.CLEARANCE_SCHEMA in logged  # a body over a ground has its clearance
    for name, current in CURRENT_SCHEMAS.items():
        if name not in logged:
            continue
        proto = descriptor_pb2.DescriptorProto()
        current.DESCRIPTOR.CopyToProto(proto)
        assert _fields(_logged_descriptor(logged[name].data, name)) == _fields(proto), (
            f"{name}: the current schema differs from the one in {golden.log_path.name}; "
            f"bump LOG_FORMAT_VERSION and regenerate the golden logs"
        )
    point = descriptor_pb2.DescriptorProto()
    pb.ContactPoint.DESCRIPTOR.CopyToProto(point)
    logged_point = _logged_descriptor(
        logged[logformat.CONTACTS_SCHEMA].data, "impactlab.ContactPoint"
    )
    assert _fields(logged_point) == _fields(point)
    # every payload decodes with today's generated classes, with no unknown field left over
    with open(golden.log_path, "rb") as stream:
        reader = make_reader(stream)
        for schema, channel, message in reader.iter_messages():
            cls = CURRENT_SCHEMAS.get(schema.name)
            if cls is None:
                continue
            decoded = cls.FromString(message.data)
            assert len(UnknownFieldSet(decoded)) == 0, channel.topic
            points = getattr(decoded, "points", [])
            assert all(len(UnknownFieldSet(p)) == 0 for p in points), channel.topic
    run = load_log(golden.log_path)
    for frame in run.bodies.values():
        assert set(BODY_FIELDS) <= set(frame.columns) and frame.height
    assert set(POINT_FIELDS) <= set(run.contacts.columns) and run.contacts.height
    assert set(ENERGY_FIELDS) <= set(run.energy.columns) and run.energy.height


def test_a_changed_contact_parameter_fails_with_a_precise_message(tmp_path):
    golden = next(g for g in GOLDENS if g.name == "drop_bounces")
    changed = record_golden(golden, tmp_path, overrides=["contact.solref=[-100000.0, -70.0]"])
    diff = compare_golden(golden.log_path, changed)
    assert not diff.equal
    report = diff.report()
    # the first logged contact is where a contact parameter can first show
    first_contact = int(load_log(golden.log_path).contacts["t_ns"].min())
    first = diff.diverged_fields[0]
    assert first.first_t_ns == first_contact
    head = report.splitlines()[0]
    assert str(golden.log_path) in head and str(changed) in head
    assert f"first at t = {fmt_t(first_contact)} s in" in head
    assert f"/bodies/ball/state vz: first diverges at t = {fmt_t(first_contact)} s" in report, (
        report
    )
    assert f"/contacts normal_force: first diverges at t = {fmt_t(first_contact)} s" in report
    assert (
        "metadata impactlab.run spec: contact.solref: A [-100000.0, -63.245553], B [-100000.0, -70.0]"
        in report
    )
    assert "attachment model.xml: differs from line" in report


@pytest.mark.slow
def test_analysis_of_the_golden_logs_reproduces_the_golden_tables(tmp_path):
    from impactlab.golden import TABLE_ATOL, TABLE_RTOL, table_change

    tables = analysis_tables(LOGS_DIR, tmp_path)
    for name in RESULT_TABLES:
        golden = pl.read_parquet(RESULTS_DIR / f"{name}.parquet")
        assert golden.height, name
        assert_frame_equal(
            tables[name], golden, check_exact=False, rel_tol=TABLE_RTOL, abs_tol=TABLE_ATOL
        )
        assert table_change(tables[name], golden) is None
        assert table_change(tables[name].head(-1), golden) is not None
    runs = tables["runs"]
    assert runs.height == len(GOLDENS)
    assert sorted(json.loads(s) != {} for s in runs["sweep"]) == [False] * 4 + [True]


# ---------------------------------------------------------------------------------------------
# any CPU: a recording that differs from its golden log in the last bits agrees with it


def _nudge_float(x: float, rel: float | None) -> float:
    """One unit in the last place up, or `rel` relative (zeros stay zero)."""
    if rel is None:
        return float(np.nextafter(x, np.inf)) if x != 0.0 else x
    return x * (1.0 + rel)


def _nudge_text(text: str, rel: float | None) -> str:
    """Every decimal number with a fraction in `text` nudged."""
    return re.sub(
        r"-?\d+\.\d+(?:e-?\d+)?", lambda m: repr(_nudge_float(float(m.group()), rel)), text
    )


def nudged(golden: Golden, path: Path, *, rel: float | None = None) -> Path:
    """The golden log as another machine could record it: every decoded value (body states,
    contact points, energy), the numbers of its metadata and of model.xml moved by one unit
    in the last place (or by `rel`), written with the official writer."""
    with open(golden.log_path, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        meta = [(m.name, dict(m.metadata)) for m in reader.iter_metadata()]
        attachments = list(reader.iter_attachments())
        messages = [(s, c, m) for s, c, m in reader.iter_messages(log_time_order=False)]
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start(profile="", library="nudged")
        cids = register_like(writer, summary)
        for name, values in meta:
            for key in ("timestep_s", "bodies"):
                if key in values:
                    values[key] = _nudge_text(values[key], rel)
            writer.add_metadata(name, values)
        for schema, channel, message in messages:
            data = message.data
            cls = CURRENT_SCHEMAS.get(schema.name)
            if cls is not None:
                msg = cls.FromString(data)
                targets = list(getattr(msg, "points", [])) or [msg]
                for target in targets:
                    for f in target.DESCRIPTOR.fields:
                        if f.type != f.TYPE_DOUBLE:
                            continue
                        if f.is_repeated:  # the clearance's distances
                            values = getattr(target, f.name)
                            values[:] = [_nudge_float(v, rel) for v in values]
                        else:
                            setattr(target, f.name, _nudge_float(getattr(target, f.name), rel))
                data = msg.SerializeToString()
            writer.add_message(
                cids[channel.id],
                log_time=message.log_time,
                publish_time=message.log_time,
                data=data,
            )
        for a in attachments:
            text = _nudge_text(a.data.decode(), rel).encode()
            writer.add_attachment(a.create_time, a.log_time, a.name, a.media_type, text)
        writer.finish()
    return path


@pytest.mark.parametrize("golden", READ)
def test_last_bit_differences_agree_with_the_golden_log(golden: Golden, tmp_path):
    """Another CPU may round MuJoCo's or numpy's results differently in the last bit: such a
    recording agrees with its golden log, although it differs bit for bit."""
    other = nudged(golden, tmp_path / "other-cpu.mcap")
    exact = diff_logs(load_log(golden.log_path), load_log(other), tolerance=EXACT)
    assert not exact.equal  # the nudge changed values, metadata and model.xml
    assert exact.diverged_fields and any(m.key == "bodies" for m in exact.meta)
    assert any(not a.equal for a in exact.attachments)
    diff = compare_golden(golden.log_path, other)
    assert diff.equal, diff.report()


@pytest.mark.parametrize("golden", READ[:2])
def test_a_change_far_below_what_matters_is_still_caught(golden: Golden, tmp_path):
    """1e-9 relative is far below any physical change and far above the last bit."""
    changed = nudged(golden, tmp_path / "changed.mcap", rel=1e-9)
    diff = compare_golden(golden.log_path, changed)
    assert not diff.equal
    assert any(f.channel.startswith("/bodies/") for f in diff.diverged_fields)
    assert any(m.key == "bodies" for m in diff.meta)
    from impactlab.golden import golden_tolerance

    tol = golden_tolerance(load_log(golden.log_path))
    assert tol.rtol == 1e-12 and max(tol.fields.values()) < 1e-8


@pytest.mark.parametrize("golden", READ[:2])
def test_a_work_near_zero_is_held_to_its_channels_joules(golden: Golden):
    """Every field of /energy/work is a sum of works in J: a kind whose work is a sum of
    last-bit noise (the solver's, about 1e-16 J per step) is held to the scale of the largest
    work, not to 1e-12 of its own noise, which a machine with other vector kernels misses."""
    from impactlab.golden import SUMMED_RTOL, golden_tolerance
    from impactlab.tools.diff import channel_tables

    log = load_log(golden.log_path)
    tol = golden_tolerance(log)
    kinds = channel_tables(log)["/energy/work"][2]
    largest = max(float(log.work[k].abs().max() or 0.0) for k in kinds)
    assert "solver" in kinds and largest > 0
    for kind in kinds:
        assert tol.atol_for("/energy/work", kind) == pytest.approx(SUMMED_RTOL * largest)
