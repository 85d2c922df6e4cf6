"""`impactlab diff`: equal logs pass, every kind of difference is reported by channel, field
and time, tolerances work, bad input is one line and exit code 2."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer
from specs import DIRECT, drop, toml

from impactlab.cli import main
from impactlab.logs import format as logformat
from impactlab.logs.load import load_log
from impactlab.proto import impactlab_pb2 as pb
from impactlab.record import plan, record_runs
from impactlab.tools.diff import (
    EXACT,
    Tolerance,
    compare_attachments,
    compare_channel,
    compare_meta,
    diff_logs,
    fmt_t,
)

SPEC = toml(
    drop("difftest", z=0.3, timestep=0.0001, contact=DIRECT, max_time=0.5, bounces=1, every=5)
)
STATE = "/bodies/ball/state"


def record_spec(out: Path, *overrides: str) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    spec = out / "difftest.toml"
    spec.write_text(SPEC)
    (result,) = record_runs(plan([spec], overrides=overrides), out / "logs")
    return result.path


Edit = Callable[[str, int, bytes], bytes | None]


def rewrite(
    src: Path,
    dst: Path,
    *,
    message: Edit | None = None,
    metadata: Callable[[str, dict[str, str]], dict[str, str]] | None = None,
) -> Path:
    """Copy an MCAP log record by record, editing (or dropping: None) messages and metadata."""
    with open(src, "rb") as stream, open(dst, "wb") as out:
        reader = make_reader(stream)
        header, summary = reader.get_header(), reader.get_summary()
        writer = Writer(out)
        writer.start(profile=header.profile, library=header.library)
        schema_ids = {
            s.id: writer.register_schema(s.name, s.encoding, s.data)
            for s in summary.schemas.values()
        }
        channel_ids = {
            c.id: writer.register_channel(
                c.topic, c.message_encoding, schema_ids[c.schema_id], dict(c.metadata)
            )
            for c in summary.channels.values()
        }
        for _, channel, msg in reader.iter_messages():
            data = message(channel.topic, msg.log_time, msg.data) if message else msg.data
            if data is not None:
                writer.add_message(
                    channel_ids[channel.id], msg.log_time, data, msg.publish_time, msg.sequence
                )
        for a in reader.iter_attachments():
            writer.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)
        for m in reader.iter_metadata():
            values = dict(m.metadata)
            writer.add_metadata(m.name, metadata(m.name, values) if metadata else values)
        writer.finish()
    return dst


def shift_z(delta: float, from_t_ns: int) -> Edit:
    def edit(topic: str, t_ns: int, data: bytes) -> bytes:
        if topic != STATE or t_ns < from_t_ns:
            return data
        msg = pb.BodyState.FromString(data)
        msg.z += delta
        return msg.SerializeToString()

    return edit


def run_cli(capsys, *args: str | Path) -> tuple[int, str, str]:
    code = main(["diff", *map(str, args)])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    return record_spec(tmp_path_factory.mktemp("base"))


def test_identical_logs_are_equal(base, capsys):
    code, out, err = run_cli(capsys, base, base)
    assert (code, err) == (0, "")
    assert out.startswith(f"{base} and {base} are equal within atol 1e-09, rtol 1e-09 (7 channels,")


def test_recording_twice_gives_bitwise_equal_logs(base, tmp_path, capsys):
    again = record_spec(tmp_path)
    # bitwise: both recorded on this machine in this session (across machines: test_golden)
    # the spec's path is compared by default: the two specs are in different folders
    code, out, _ = run_cli(capsys, base, again, "--atol", "0", "--rtol", "0")
    assert code == 1
    assert out.splitlines()[1].startswith("  metadata impactlab.run source: A '")
    assert len(out.splitlines()) == 2
    code, out, _ = run_cli(
        capsys, base, again, "--atol", "0", "--rtol", "0", "--ignore-meta", "source"
    )
    assert code == 0, out


def test_perturbed_recording_names_channel_field_and_time(base, tmp_path, capsys):
    other = record_spec(tmp_path, "ball.pos=[0.0, 0.0, 0.3000001]")
    code, out, _ = run_cli(capsys, base, other)
    assert code == 1
    lines = out.splitlines()
    assert lines[0].startswith(f"{base} (A) and {other} (B) differ (atol 1e-09, rtol 1e-09)")
    assert lines[0].endswith("first at t = 0 s in /bodies/ball/state z")
    assert lines[1].startswith(
        "  /bodies/ball/state z: first diverges at t = 0 s (A 0.3, B 0.3000001, |d| = 1e-07 > tol"
    )
    assert any(line.startswith("  /energy potential: first diverges at t = 0 s") for line in lines)
    assert (
        "  metadata impactlab.run spec: bodies.ball.pos: A [0.0, 0.0, 0.3], B [0.0, 0.0, 0.3000001]"
        in lines
    )
    # x, y and the quaternion are untouched
    assert not any(line.startswith(f"  {STATE} x:") or " qw:" in line for line in lines)


def test_shorter_run_reports_the_missing_messages(base, tmp_path, capsys):
    short = record_spec(tmp_path, "stop.max_time=0.1")
    code, out, _ = run_cli(capsys, base, short)
    assert code == 1
    a, b = load_log(base), load_log(short)
    last_b = int(b.bodies["ball"]["t_ns"].max())
    extra = a.bodies["ball"].filter(pl.col("t_ns") > last_b)["t_ns"]
    first, last = fmt_t(extra.min()), fmt_t(extra.max())
    assert f"  {STATE}: {extra.len()} messages only in A, t = {first} .. {last} s" in out
    assert f"  /energy: {extra.len()} messages only in A, t = {first} .. {last} s" in out
    assert "  /contacts: channel only in A:" in out  # B ends before the bounce
    assert "  metadata impactlab.run spec: stop.max_time: A 0.5, B 0.1" in out
    assert (
        "  metadata impactlab.outcome reason: A 'apex after bounce 1', B 'time limit 0.1 s'" in out
    )
    assert "first diverges" not in out  # the common part is identical


def test_metadata_difference_is_reported_and_can_be_ignored(base, tmp_path, capsys):
    def edit(name: str, values: dict[str, str]) -> dict[str, str]:
        if name == logformat.RUN_METADATA:
            values |= {"description": "another run", "impactlab_version": "99.0"}
        return values

    other = rewrite(base, tmp_path / "meta.mcap", metadata=edit)
    code, out, _ = run_cli(capsys, base, other)
    assert code == 1
    assert out.splitlines()[1:] == ["  metadata impactlab.run description: A '', B 'another run'"]
    assert run_cli(capsys, base, other, "--ignore-meta", "description")[0] == 0
    code, out, _ = run_cli(capsys, base, other, "--ignore-meta", "description", "--all-meta")
    assert code == 1
    assert "metadata impactlab.run impactlab_version: A '0.1.0', B '99.0'" in out


def test_tolerance_options_let_a_small_difference_pass(base, tmp_path, capsys):
    other = rewrite(base, tmp_path / "z.mcap", message=shift_z(3e-7, 100_000_000))
    code, out, _ = run_cli(capsys, base, other)
    assert code == 1
    assert out.splitlines()[1].startswith(f"  {STATE} z: first diverges at t = 0.1 s")
    assert len(out.splitlines()) == 2  # nothing else differs
    for option in (
        ["--atol", "1e-6"],
        ["--rtol", "1e-5"],  # |z| >= 0.1: 1e-5 * 0.1 > 3e-7
        ["--tol", "z=1e-6"],
        ["--tol", f"{STATE}:z=1e-6"],
    ):
        code, out, _ = run_cli(capsys, base, other, *option)
        assert code == 0, (option, out)
        assert (
            "1 field(s) differ within tolerance, largest |d| = 3e-07 in /bodies/ball/state z" in out
        )
    assert run_cli(capsys, base, other, "--tol", "vz=1e-6")[0] == 1
    assert run_cli(capsys, base, other, "--tol", "/energy:z=1e-6")[0] == 1


def test_dropped_channel_and_changed_text(base, tmp_path, capsys):
    def edit(topic: str, t_ns: int, data: bytes) -> bytes | None:
        if topic == logformat.CONTACTS_TOPIC:
            return None
        if topic == logformat.EVENTS_TOPIC:
            return data.replace(b"apex after bounce 1", b"apex after bounce 2")
        return data

    other = rewrite(base, tmp_path / "drop.mcap", message=edit)
    code, out, _ = run_cli(capsys, base, other)
    assert code == 1
    n = load_log(base).contacts["t_ns"].n_unique()
    assert f"  /contacts: channel only in A: {n} messages, t = " in out
    end = fmt_t(load_log(base).bodies["ball"]["t_ns"].max())
    assert (
        f"  /events message: first differs at t = {end} s: "
        "A 'completed: apex after bounce 1', B 'completed: apex after bounce 2'; 1 of 1 differ"
    ) in out


def test_json_report(base, tmp_path, capsys):
    other = rewrite(base, tmp_path / "z.mcap", message=shift_z(3e-7, 100_000_000))
    code, out, _ = run_cli(capsys, base, other, "--json")
    assert code == 1
    data = json.loads(out)
    assert (data["equal"], data["a"], data["b"]) == (False, str(base), str(other))
    assert data["tolerance"] == {"atol": 1e-9, "rtol": 1e-9, "fields": {}}
    (state,) = [c for c in data["channels"] if c["channel"] == STATE]
    (z,) = state["fields"]
    assert (z["field"], z["diverged"], z["first_t_s"], z["first_t_ns"]) == (
        "z",
        True,
        0.1,
        100_000_000,
    )
    assert z["max_abs"] == pytest.approx(3e-7)
    assert data["differences"][0].startswith(f"{STATE} z: first diverges at t = 0.1 s")
    assert data["attachments"] == [
        {
            "name": "model.xml",
            "equal": True,
            "size_a": z_size,
            "size_b": z_size,
            "first_line": None,
            "line_a": None,
            "line_b": None,
        }
        for z_size in [data["attachments"][0]["size_a"]]
    ]


def _mcap_without_impactlab_channels(path: Path) -> Path:
    with open(path, "wb") as out:
        writer = Writer(out)
        writer.start()
        schema = writer.register_schema("other.Thing", "jsonschema", b"{}")
        channel = writer.register_channel("/thing", "json", schema)
        writer.add_message(channel, 0, b"{}", 0)
        writer.finish()
    return path


@pytest.mark.parametrize(
    ("case", "problem"),
    [
        ("missing", "file not found"),
        ("text", "not an MCAP file (bad magic bytes)"),
        ("empty", "not an MCAP file (bad magic bytes)"),
        ("folder", "is a folder, not a log"),
        ("foreign", "not an impactlab log"),
    ],
)
@pytest.mark.parametrize("side", ["A", "B"])
def test_bad_input_is_one_line_and_exit_2(base, tmp_path, capsys, case, problem, side):
    bad = tmp_path / f"{case}.mcap"
    if case == "text":
        bad.write_text("not a log\n")
    elif case == "empty":
        bad.write_bytes(b"")
    elif case == "folder":
        bad.mkdir()
    elif case == "foreign":
        _mcap_without_impactlab_channels(bad)
    args = (bad, base) if side == "A" else (base, bad)
    code, out, err = run_cli(capsys, *args)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1
    assert err.startswith(f"impactlab: error: {bad}: {problem}")


@pytest.mark.parametrize(
    "option",
    [["--tol", "z"], ["--tol", "=1"], ["--tol", "z=abc"], ["--atol", "-1"], ["--rtol", "nan"]],
)
def test_bad_options_exit_2(base, capsys, option):
    with pytest.raises(SystemExit) as exc:
        main(["diff", str(base), str(base), *option])
    assert exc.value.code == 2
    assert "impactlab diff: error: argument" in capsys.readouterr().err


def test_truncated_log_is_compared_with_a_note(base, tmp_path, capsys):
    data = base.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    code, out, _ = run_cli(capsys, base, cut)
    assert code == 1
    assert "note: B is incomplete:" in out
    assert "metadata impactlab.outcome outcome: only in A ('completed')" in out


# pure functions


def test_numbers_nan_and_infinities():
    t = np.arange(5, dtype=np.int64) * 1000
    a = pl.DataFrame({"t_ns": t, "v": [0.0, math.nan, 1.0, math.inf, -0.0]})
    b = pl.DataFrame({"t_ns": t, "v": [0.0, math.nan, 1.0 + 1e-12, 1e300, 0.0]})
    ch = compare_channel("/x", a, b, ("t_ns",), ("v",), Tolerance(atol=1e-9, rtol=0.0))
    (f,) = ch.fields
    assert (f.differing, f.beyond, f.first_t_ns, f.max_abs) == (2, 1, 3000, math.inf)
    a2 = a.with_columns(pl.when(pl.col("t_ns") == 1000).then(0.0).otherwise("v").alias("v"))
    (g,) = compare_channel("/x", a2, b, ("t_ns",), ("v",), EXACT).fields
    assert g.first_t_ns == 1000 and g.first_abs == math.inf


def test_missing_rows_and_point_counts():
    a = pl.DataFrame({"t_ns": [0, 0, 10, 20], "point": [0, 1, 0, 0], "f": [1.0, 2.0, 3.0, 4.0]})
    b = pl.DataFrame({"t_ns": [0, 10, 30], "point": [0, 0, 0], "f": [1.0, 3.0, 5.0]})
    ch = compare_channel("/contacts", a, b, ("t_ns", "point"), ("f",), EXACT)
    assert (ch.only_a.count, ch.only_a.first_t_ns, ch.only_b.count, ch.only_b.first_t_ns) == (
        1,
        20,
        1,
        30,
    )
    (count,) = ch.fields
    assert (count.field, count.first_t_ns, count.first_a, count.first_b) == (
        "number of points",
        0,
        2,
        1,
    )


def test_meta_json_paths_and_missing_keys():
    a = {
        "spec": json.dumps({"contact": {"solref": [1, 2]}, "bodies": {"b": {"mass": 1}}}),
        "x": "1",
    }
    b = {"spec": json.dumps({"contact": {"solref": [1, 3]}, "bodies": {"b": {"mass": 1}}})}
    spec, x = compare_meta(a, b)
    assert spec.changes == ("contact.solref: A [1, 2], B [1, 3]",)
    assert (x.key, x.a, x.b) == ("x", "1", None)
    assert compare_meta(a, b, ignore=["spec", "x"]) == []


def test_attachments_first_differing_line():
    a = {"model.xml": b"<a>\n  <b x='1'/>\n</a>\n", "same": b"x"}
    b = {"model.xml": b"<a>\n  <b x='2'/>\n</a>\n", "same": b"x", "extra": b""}
    extra, model, same = compare_attachments(a, b)
    assert (extra.equal, extra.size_a, extra.size_b) == (False, None, 0)
    assert (model.first_line, model.line_a, model.line_b) == (2, "<b x='1'/>", "<b x='2'/>")
    assert same.equal


def test_fmt_t_is_exact():
    assert [fmt_t(0), fmt_t(412_300_000), fmt_t(1_000_000_000), fmt_t(1_000_010)] == [
        "0",
        "0.4123",
        "1",
        "0.00100001",
    ]


def test_tolerance_rejects_negative_values():
    with pytest.raises(ValueError, match="atol"):
        Tolerance(atol=-1.0)
    assert Tolerance(fields={"z": 1.0, "/e:z": 2.0}).atol_for("/e", "z") == 2.0
    assert Tolerance(fields={"z": 1.0}).atol_for("/b", "z") == 1.0


def test_diff_logs_of_a_log_with_itself_is_equal(base):
    run = load_log(base)
    assert diff_logs(run, run, tolerance=EXACT).equal


def test_numbers_in_metadata_and_model_compare_within_the_tolerance():
    """A last-bit difference in a number of the metadata or the model is no difference (another
    CPU may round numpy's exp differently); a real one is, and text around numbers is exact."""
    tol = Tolerance(atol=0.0, rtol=1e-12)
    a = {
        "timestep_s": "1e-05",
        "spec": json.dumps({"contact": {"solref": [-436000.0, -44.87587001604219]}}),
    }
    b = {
        "timestep_s": "1.0000000000000002e-05",
        "spec": json.dumps({"contact": {"solref": [-436000.0000000001, -44.875870016042194]}}),
    }
    assert compare_meta(a, b, tolerance=tol) == []
    assert [m.key for m in compare_meta(a, b)] == ["spec", "timestep_s"]  # EXACT by default
    c = {**b, "spec": json.dumps({"contact": {"solref": [-436000.0, -44.9]}})}
    (spec,) = compare_meta(a, c, tolerance=tol)
    assert spec.changes == (
        "contact.solref: A [-436000.0, -44.87587001604219], B [-436000.0, -44.9]",
    )
    assert [m.key for m in compare_meta({"v": "1"}, {"v": "1.0"}, tolerance=tol)] == ["v"]
    assert [m.key for m in compare_meta({"e": "ball"}, {"e": "balls"}, tolerance=tol)] == ["e"]
    model_a = {"model.xml": b'<pair solref="-436000.0000000001 -44.87587001604219"/>\n'}
    model_b = {"model.xml": b'<pair solref="-436000 -44.875870016042194"/>\n'}
    model_c = {"model.xml": b'<pair solimp="-436000 -44.875870016042194"/>\n'}
    assert compare_attachments(model_a, model_b, tolerance=tol)[0].equal
    assert not compare_attachments(model_a, model_b)[0].equal
    (other,) = compare_attachments(model_a, model_c, tolerance=tol)
    assert not other.equal and other.first_line == 1
