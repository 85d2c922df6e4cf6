"""The fast paths agree with the protobuf library and the official mcap reader, value for value."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
from mcap_protobuf.writer import Writer as ProtobufWriter
from paths import EXPERIMENTS

from impactlab.logs import messages
from impactlab.logs.load import load_log
from impactlab.logs.messages import BODY_FIELDS, POINT_FIELDS, Template
from impactlab.proto import impactlab_pb2 as pb
from impactlab.record import plan, record_runs


def test_template_round_trip_matches_the_library():
    rng = np.random.default_rng(0)
    values = rng.normal(size=(50, 13))
    values[3] = 0.0  # zeros are written explicitly, and still decode as zeros
    payloads = messages.body_state().encode(values)
    for row, payload in zip(values, payloads, strict=True):
        msg = pb.BodyState.FromString(payload.tobytes())
        assert [getattr(msg, f) for f in BODY_FIELDS] == row.tolist()
    assert (messages.body_state().decode(payloads) == values).all()


def test_template_refuses_other_layouts():
    layout = messages.body_state()
    library = pb.BodyState(x=1.0, vz=2.0).SerializeToString()  # zeros omitted: shorter
    assert layout.decode(np.frombuffer(library, np.uint8)[None]) is None
    payload = layout.encode(np.ones((1, 13)))
    payload[0, 0] ^= 0xFF  # a tag byte changed
    assert layout.decode(payload) is None


def test_template_needs_a_fixed_layout():
    def setter(msg, values):
        msg.geom1 = "a" * int(values[0])

    with pytest.raises((ValueError, TypeError)):
        Template.learn(pb.Contact(), setter, 1)


@pytest.fixture(scope="module")
def logs(tmp_path_factory) -> list[Path]:
    out = tmp_path_factory.mktemp("logs")
    specs = [EXPERIMENTS / "collision.toml", EXPERIMENTS / "drop.toml"]
    runs = plan(specs, overrides=["stop.max_time=0.8"])
    return [r.path for r in record_runs(runs, out)]


@pytest.mark.slow
def test_loader_equals_the_official_reader(logs):
    for path in logs:
        run = load_log(path)
        with open(path, "rb") as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            by_topic: dict[str, list] = {}
            for _, channel, message, proto in reader.iter_decoded_messages():
                by_topic.setdefault(channel.topic, []).append((message.log_time, proto))
        for name, frame in run.bodies.items():
            official = by_topic[f"/bodies/{name}/state"]
            assert frame["t_ns"].to_list() == [t for t, _ in official]
            for f in BODY_FIELDS:
                assert frame[f].to_list() == [getattr(m, f) for _, m in official], f
        assert run.energy["total"].to_list() == [m.total for _, m in by_topic["/energy"]]
        contacts = [(t, p) for t, m in by_topic.get("/contacts", []) for p in m.points]
        assert contacts or "collision" not in path.name  # the collision's balls do touch
        assert run.contacts["t_ns"].to_list() == [t for t, _ in contacts]  # in message order
        for f in POINT_FIELDS:
            assert run.contacts[f].to_list() == [getattr(p, f) for _, p in contacts], f


def test_loader_reads_files_of_the_official_writer():
    """Chunks that define their own channels and hold library-encoded messages: slow path."""
    buf = io.BytesIO()
    writer = ProtobufWriter(buf)
    for i in range(20):
        msg = pb.BodyState(x=float(i), vz=-1.0 * i)
        writer.write_message("/bodies/ball/state", msg, log_time=i * 1000, publish_time=i * 1000)
        writer.write_message(
            "/energy", pb.Energy(kinetic=i, total=i), log_time=i * 1000, publish_time=i * 1000
        )
    writer.finish()
    path = Path(__file__).parent / "_tmp_official.mcap"
    try:
        path.write_bytes(buf.getvalue())
        run = load_log(path)
    finally:
        path.unlink(missing_ok=True)
    assert run.bodies["ball"]["x"].to_list() == [float(i) for i in range(20)]
    assert run.energy["kinetic"].to_list() == [float(i) for i in range(20)]
    assert run.partial  # no impactlab metadata


@pytest.mark.slow
def test_chunk_writer_output_passes_the_official_summary_checks(logs):
    for path in logs:
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            summary = reader.get_summary()
            count = sum(1 for _ in reader.iter_messages())
        assert summary.statistics.message_count == count
        assert sum(summary.statistics.channel_message_counts.values()) == count
        assert summary.statistics.chunk_count == len(summary.chunk_indexes)
        for index in summary.chunk_indexes:
            assert index.message_start_time <= index.message_end_time
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            ordered = [m.log_time for _, _, m in reader.iter_messages(log_time_order=True)]
        assert ordered == sorted(ordered)
