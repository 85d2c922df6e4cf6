"""The decoder against plain references: the frames `load_log` builds hold exactly what the
protobuf library decodes from each message (read with the official mcap reader), on the
golden logs and on logs of several experiments; a damaged index anywhere loses nothing."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from mcap.reader import make_reader
from polars.testing import assert_frame_equal

from impactlab.logs.load import load_log
from impactlab.logs.messages import BODY_FIELDS, ENERGY_FIELDS, POINT_FIELDS
from impactlab.logs.reader import read_mcap
from impactlab.proto import impactlab_pb2 as pb

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = sorted((ROOT / "tests" / "golden" / "logs").glob("*.mcap"))
EXPERIMENTS = ["drop.toml", "collision.toml", "free_fall.toml"]

# a drop long enough for several 1 MiB chunks, contacts in some steps only
LONG_DROP = """
name = "long_drop"
[options]
timestep = 0.0005
[contact]
solref = [0.02, 0.5]
[bodies.ball]
radius = 0.1
mass = 1.0
pos = [0.0, 0.0, 0.6]
[stop]
max_time = 2.5
"""


@pytest.fixture(scope="module")
def long_log(record_spec) -> Path:
    """A drop of several chunks, contacts in some steps only."""
    return record_spec("long_drop", LONG_DROP)[0]


@pytest.fixture(scope="module")
def logs(long_log, tmp_path_factory) -> list[Path]:
    """The golden logs, the experiments' logs and the long drop (last)."""
    from impactlab.record import plan, record_runs

    folder = tmp_path_factory.mktemp("experiments")
    specs = [ROOT / "experiments" / name for name in EXPERIMENTS]
    return [*GOLDEN, *(r.path for r in record_runs(plan(specs), folder)), long_log]


def _messages(content) -> dict[str, tuple[list[int], list[bytes]]]:
    out = {}
    for channel in content.channels.values():
        times, payloads = [], []
        for t, data in channel.pieces:
            times += t.tolist()
            payloads += data if isinstance(data, list) else [bytes(r) for r in data]
        out[channel.topic] = (times, payloads)
    return out


def test_the_long_log_spans_chunks_and_reads_each_channel_chunk_by_chunk(long_log):
    chunks = make_reader(long_log.open("rb")).get_summary().chunk_indexes
    assert len(chunks) >= 3
    content = read_mcap(long_log)
    assert not content.problems
    cid, state = next((i, c) for i, c in content.channels.items() if c.topic.endswith("/state"))
    assert state.count == 5001
    assert len(state.pieces) == sum(cid in c.message_index_offsets for c in chunks) >= 3
    assert all(rows.shape[1] == 13 * 9 for _, rows in state.pieces)


def _reference(path: Path) -> dict[str, pl.DataFrame]:
    """Frames decoded message by message with the protobuf library (time order kept)."""
    rows: dict[str, list] = defaultdict(list)
    with path.open("rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            t, data = message.log_time, message.data
            if schema.name == "impactlab.BodyState":
                m = pb.BodyState.FromString(data)
                body = channel.metadata.get("body", "")
                rows[f"body:{body}"].append([t, *(getattr(m, f) for f in BODY_FIELDS)])
            elif schema.name == "impactlab.Energy" and channel.topic == "/energy":
                m = pb.Energy.FromString(data)
                rows["energy"].append([t, *(getattr(m, f) for f in ENERGY_FIELDS)])
            elif schema.name == "impactlab.Contacts":  # sides: ids into the metadata's lists
                geoms = json.loads(channel.metadata["geoms"])
                bodies = json.loads(channel.metadata["bodies"])
                for i, p in enumerate(pb.Contacts.FromString(data).points):
                    g1, g2, b1, b2 = (
                        geoms[p.geom1],
                        geoms[p.geom2],
                        bodies[p.geom1],
                        bodies[p.geom2],
                    )
                    values = (getattr(p, f) for f in POINT_FIELDS)
                    rows[f"contacts:{g1}/{g2}"].append([t, g1, g2, b1, b2, i, *values])
            elif schema.name == "impactlab.Clearance":
                m = pb.Clearance.FromString(data)
                body = channel.metadata.get("body", "")
                rows[f"clearance:{body}"] += [[t, d] for d in m.distance]
    frames = {}
    for key, table in rows.items():
        if key.startswith("contacts:"):
            names = ["t_ns", "geom1", "geom2", "body1", "body2", "point", *POINT_FIELDS]
        elif key.startswith("clearance:"):
            names = ["t_ns", "clearance_m"]
        else:
            names = ["t_ns", *(BODY_FIELDS if key.startswith("body:") else ENERGY_FIELDS)]
        frame = pl.DataFrame(table, schema=names, orient="row")
        frames[key] = frame.sort("t_ns", maintain_order=True)
    return frames


@pytest.mark.slow
def test_frames_hold_what_the_protobuf_library_decodes(logs):
    for path in logs:
        run = load_log(path)
        expected = _reference(path)
        got = {f"body:{k}": v for k, v in run.bodies.items()} | {"energy": run.energy}
        for (g1, g2), frame in run.contacts.group_by(["geom1", "geom2"], maintain_order=True):
            got[f"contacts:{g1}/{g2}"] = frame.with_columns(pl.col("point").cast(pl.Int64))
        for (body,), frame in run.clearance.group_by(["body"], maintain_order=True):
            got[f"clearance:{body}"] = frame
        assert set(expected) <= set(got), path
        assert all(got[k].height == 0 for k in set(got) - set(expected)), path
        for key, want in expected.items():
            frame = got[key]
            assert (frame["run_id"] == run.run_id).all()
            assert np.array_equal(frame["t_s"].to_numpy(), frame["t_ns"].to_numpy() / 1e9)
            assert_frame_equal(frame.select(want.columns), want, check_exact=True)


def test_a_fixed_byte_changed_in_any_row_is_another_layout():
    """A payload of another layout is refused wherever it is among many; every double comes
    back in its column."""
    from impactlab.logs import messages

    layout = messages.clearance(26)
    n = 5000
    values = np.arange(n * layout.slots.size, dtype=np.float64).reshape(n, -1)
    payloads = layout.encode(values)
    assert np.array_equal(layout.decode(payloads), values)
    for row in (0, n // 2, n - 1):
        bad = payloads.copy()
        bad[row, np.flatnonzero(layout.fixed)[-1]] ^= 1
        assert layout.decode(bad) is None


def test_each_read_gets_its_own_channel_metadata(tmp_path):
    from mcap.writer import Writer

    path = tmp_path / "big_schema.mcap"
    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile="", library="test")
        big = writer.register_schema("test.Big", "protobuf", b"x" * 100_000)
        small = writer.register_schema("test.Small", "protobuf", b"y")
        for cid, schema in ((1, big), (2, small)):
            c = writer.register_channel(f"/c{cid}", "protobuf", schema, {"k": str(cid)})
            writer.add_message(c, log_time=1, data=b"abc", publish_time=1)
        writer.finish()
    first, second = read_mcap(path), read_mcap(path)
    assert [c.schema for c in first.channels.values()] == ["test.Big", "test.Small"]
    assert [c.metadata for c in second.channels.values()] == [{"k": "1"}, {"k": "2"}]
    next(iter(first.channels.values())).metadata["k"] = "changed"
    assert next(iter(second.channels.values())).metadata == {"k": "1"}
    assert next(iter(read_mcap(path).channels.values())).metadata == {"k": "1"}


def _edit_index(data: bytearray, chunk: int, edit) -> None:
    """Apply `edit(entries)` to the first message index after the `chunk`-th chunk (0-based),
    its entries a writable (n, 2) uint64 view of the file (log_time, offset)."""
    pos, seen = 8, -1
    while pos < len(data):
        op, length = data[pos], int.from_bytes(data[pos + 1 : pos + 9], "little")
        if op == 0x06:  # Chunk
            seen += 1
        elif op == 0x07 and seen == chunk:  # MessageIndex: channel u16, entries (u32 bytes)
            size = int.from_bytes(data[pos + 11 : pos + 15], "little")
            edit(np.frombuffer(data, "<u8", count=size // 8, offset=pos + 15).reshape(-1, 2))
            return
        pos += 9 + length
    raise AssertionError("no such message index")


@pytest.mark.parametrize("what", ["offset-past-chunk", "one-time", "other-record"])
def test_an_index_wrong_in_a_later_chunk_is_reported_and_loses_nothing(long_log, tmp_path, what):
    """A disagreement between an index and its chunk: reported, and that chunk is walked."""
    data = bytearray(long_log.read_bytes())

    def edit(entries):
        if what == "offset-past-chunk":
            entries[-1, 1] = 1 << 40
        elif what == "one-time":
            entries[len(entries) // 2, 0] += 1
        else:
            entries[3, 1] = entries[2, 1]

    _edit_index(data, 1, edit)
    path = tmp_path / "bad.mcap"
    path.write_bytes(bytes(data))
    content = read_mcap(path)
    assert [p for p in content.problems if "message index of the chunk" in p]

    def rows(c):
        return {k: sorted(zip(*v, strict=True)) for k, v in _messages(c).items()}

    assert rows(content) == rows(read_mcap(long_log))


def test_impacts_hold_each_message_field_of_the_column_name():
    """Each scalar column of `/impacts` is the protobuf field of its name (less its unit)."""
    import re

    from impactlab.logs.decode import IMPACT_SCHEMA

    path = ROOT / "tests" / "golden" / "logs" / "drop_bounces.mcap"
    run = load_log(path)
    with open(path, "rb") as stream:
        found = make_reader(stream).iter_messages(topics=["/impacts"])
        impacts = [pb.Impact.FromString(m.data) for _, _, m in found]
    assert run.impacts.height == len(impacts) > 0
    for column in list(IMPACT_SCHEMA)[1:19]:  # side1 .. open
        name = re.sub(r"_(mps|J|N|Ns|m)$", "", column)
        assert run.impacts[column].to_list() == [getattr(i, name) for i in impacts], column
