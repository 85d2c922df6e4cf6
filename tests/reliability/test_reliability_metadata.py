"""Odd metadata: every key of the log's metadata, missing, of the wrong type, out of range, or
contradicted by the channels, and message times beyond what the frames hold.

Each case is an intact log copied record by record by the official mcap writer with one thing
changed (as another tool, or a damaged byte in a record without CRC, would leave it). For
every case: the log still loads, the problem names the key, the analysis refuses the run only
when the key is one it cannot do without (masses, radii, gravity, plane, timestep, logging
stride) and otherwise analyzes it, and info, diff and replay describe, compare and convert it
without a traceback. The cases are generated from the declared schema (`KEYS`), so a new key
gets its cases without a new test.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from mcap.reader import make_reader
from mcap.records import Channel
from mcap.writer import Writer
from mcap_copy import register_like
from paths import ROOT
from specs import drop, toml

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.cli import main
from impactlab.errors import LogError
from impactlab.logs import format as logformat
from impactlab.logs.load import load_log
from impactlab.replay.recordings import write_recording
from impactlab.tools import DEFAULT_IGNORED_META
from impactlab.tools.diff import diff_logs
from impactlab.tools.info import describe

SPEC = toml(drop("odd", z=0.2, max_time=0.3))
RUN, OUTCOME = logformat.RUN_METADATA, logformat.OUTCOME_METADATA
KEYS = (*logformat.RUN_KEYS, *logformat.OUTCOME_KEYS)
ANALYSIS_KEYS = (  # docs/log-format.md
    "timestep_s",
    "log_every",
    "bodies",
    "gravity",
    "plane_z",
    "integrator",
    "ground",
    "static_potential_J",
    "half_step_s",
)
FREE_TEXT = {
    "impactlab_version",
    "mujoco_version",
    "experiment",
    "description",
    "source",
    "spec_hash",
    "reason",
}
# values of the wrong type or out of range, per kind of key (any string is a valid free text)
BAD = {
    "log_format_version": ["4", "", "1.0", "2.0", "three"],
    "run_id": ["", "   "],
    "spec": ["7", '"x"', "[1, 2]", "{", '{"bodies": [1]}', '{"contact": 3}', "[" * 3000],
    "sweep": ["7", "null", "[]", "{"],
    "sweep_index": ["x", "-1", "1.5", "", "1e3", str(10**30)],
    "sweep_size": ["x", "0", "-3", "", str(10**30)],
    "timestep_s": ["x", "", "0", "-0.001", "1e+300", "nan", "inf", "1e-12", "100"],
    "log_every": ["x", "0", "-1", "2.5", "", str(10**22)],
    "gravity": ["x", "[0, 0]", '[0, 0, "g"]', "[0, 0, 1e999]", "[0, 0, -1e300]", "{}", "true"],
    "bodies": [
        "x",
        "{}",
        '[{"mass": 1.0, "inertia": [1, 1, 1], "radius": 0.1}]',
        '[{"name": "ball", "mass": -1.0, "inertia": [1, 1, 1], "radius": 0.1}]',
        '[{"name": "ball", "mass": 1e300, "inertia": [1, 1, 1], "radius": 0.1}]',
        '[{"name": "ball", "mass": "1", "inertia": [1, 1, 1], "radius": 0.1}]',
        '[{"name": "ball", "mass": 1.0, "inertia": [1, 1], "radius": 0.1}]',
        '[{"name": "ball", "mass": 1.0, "inertia": [1, 1, 1], "radius": 0}]',
        '[{"name": "ball", "mass": 1.0, "inertia": [1, 1, 1], "radius": 0.1},'
        ' {"name": "ball", "mass": 1.0, "inertia": [1, 1, 1], "radius": 0.1}]',
    ],
    "plane_z": ["x", "nan", "1e300", "[0]"],
    "integrator": ["", "euler", "Verlet", "1"],
    "ground": [
        "x",
        "{}",
        '[{"name": "floor"}]',
        '[{"name": "floor", "type": "plane", "level_m": 1e300, "distance": true}]',
        '[{"name": "floor", "type": "plane", "level_m": 0.0, "distance": "yes"}]',
    ],
    "static_potential_J": ["x", "", "nan", "1e300"],
    "contact_targets": [
        "x",
        "{}",
        '[{"geom1": "plane"}]',
        '[{"geom1": "a", "geom2": "b", "restitution": 2, "speed_range_mps": [1, 2]}]',
        *(  # a target e(v): points of a curve, both lists or neither, ascending, e in 0..1
            '[{"geom1": "a", "geom2": "b", "restitution": 0.8, "speed_range_mps": [1, 2], '
            f"{curve}}}]"
            for curve in (
                '"curve_speed_mps": [1, 2]',
                '"curve_speed_mps": [2, 1], "curve_e": [0.8, 0.7]',
                '"curve_speed_mps": [1, 2], "curve_e": [0.8, 1.5]',
                '"curve_speed_mps": [1, 2, 3], "curve_e": [0.8, 0.7]',
                '"curve_speed_mps": [1], "curve_e": [0.8]',
                '"curve_speed_mps": "x", "curve_e": [0.8, 0.7]',
                f'"curve_speed_mps": {list(range(1, 100))}, "curve_e": {[0.5] * 99}',
            )
        ),
    ],
    "geom_contact": ["x", "[]", '{"solref": [1]}', '{"solref": [1, 2], "solimp": [1]}'],
    "separation_m": ["x", "0", "-1", "nan"],
    "half_step_s": ["x", "", "-1", "0.5", "0"],  # dt = 0.001 s with Euler: 0.0005 s
    "outcome": ["", "done", "COMPLETED"],
    "warnings": ["x", "[1]", '"a warning"', "{}"],
    "steps": ["x", "-1", "1.5", str(10**30)],
}


def cases() -> list[tuple[str, str | None]]:
    """(key, bad value) for every key and bad value; None: the key is missing."""
    out: list[tuple[str, str | None]] = [(key, None) for key in KEYS]
    out += [(key, value) for key in KEYS for value in BAD.get(key, [])]
    return out


def case_id(case: tuple[str, str | None]) -> str:
    key, value = case
    return f"{key}-missing" if value is None else f"{key}={value[:24]!r}"


@pytest.fixture(scope="module")
def intact(tmp_path_factory) -> Path:
    from impactlab.record import plan, record_runs

    folder = tmp_path_factory.mktemp("odd")
    (folder / "odd.toml").write_text(SPEC)
    (result,) = record_runs(plan([folder / "odd.toml"]), folder / "logs")
    run = load_log(result.path)
    assert not run.partial and run.contacts.height  # the ball reaches the plane
    return result.path


@pytest.fixture(scope="module")
def records(intact: Path):
    """Everything of the intact log, as the official reader gives it."""
    with open(intact, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        meta = [(m.name, dict(m.metadata)) for m in reader.iter_metadata()]
        attachments = list(reader.iter_attachments())
        messages = [(c, m) for _, c, m in reader.iter_messages(log_time_order=False)]
    return summary, meta, attachments, messages


def record_of(key: str) -> str:
    return OUTCOME if key in logformat.OUTCOME_KEYS else RUN


def rewrite(
    records,
    path: Path,
    *,
    meta=None,
    drop=None,
    topics=None,
    time=None,
    body_meta=None,
    again=None,
    twice=(),
) -> Path:
    """Copy the log with the official writer, changing metadata values (`meta`: {key: value}),
    dropping keys (`drop`), renaming topics (`topics`) or mapping message times (`time`);
    `again`: {key: value} written in a second record of the key's name after the first;
    `twice`: topics whose every message is written twice."""
    summary, metadata, attachments, messages = records
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start(profile="", library="rewrite")

        def rename(c: Channel) -> tuple[str, dict[str, str]]:
            topic = (topics or {}).get(c.topic, c.topic)
            md = dict(c.metadata)
            if topic != c.topic and "body" in md:
                md["body"] = body_meta or topic.split("/")[2]
            return topic, md

        channels = register_like(writer, summary, rename)
        for name, values in metadata:
            values = dict(values)
            for key in drop or ():
                if record_of(key) == name:
                    values.pop(key)
            values |= {k: v for k, v in (meta or {}).items() if record_of(k) == name}
            writer.add_metadata(name, values)
            if again is not None:
                writer.add_metadata(
                    name, values | {k: v for k, v in again.items() if record_of(k) == name}
                )
        for channel, m in messages:
            t = time(m.log_time) if time else m.log_time
            for _ in range(2 if channel.topic in twice else 1):
                writer.add_message(channels[channel.id], log_time=t, publish_time=t, data=m.data)
        for a in attachments:
            writer.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)
        writer.finish()
    return path


def test_the_schema_declares_every_key_the_format_has():
    from impactlab.logs import metadata

    assert set(metadata.HOLDS) == set(KEYS)
    assert set(metadata.ANALYSIS_KEYS) == set(ANALYSIS_KEYS)
    assert {k for k in KEYS if k not in FREE_TEXT} == set(BAD)  # every typed key has cases
    doc = (ROOT / "docs" / "log-format.md").read_text()
    for record, model in metadata.RECORDS.items():  # the models and the documented table
        keys = logformat.RUN_KEYS if record == logformat.RUN_METADATA else logformat.OUTCOME_KEYS
        assert set(model.__pydantic_fields__) == set(keys), record
        for key, holds in keys.items():
            needed = "needed" if key in ANALYSIS_KEYS else ""
            assert f"| `{key}` | `{record}` | {holds} | {needed} |" in doc, key


@pytest.mark.slow  # 127 cases, each read by the commands: 23 s
@pytest.mark.parametrize("case", cases(), ids=case_id)
def test_every_key_wrong_missing_or_out_of_range(tmp_path, records, intact, case):
    key, value = case
    path = tmp_path / "odd.mcap"
    if value is None:
        rewrite(records, path, drop=[key])
    else:
        rewrite(records, path, meta={key: value})

    run = load_log(path)  # never raises for metadata
    if value is None and key in logformat.RUN_KEYS_ADDED:  # older logs lack it: no problem
        assert not run.partial and key not in run.checked.problems, run.problems
        assert analyze_run(run).bounces["bounce"].count() >= 1
        return
    assert key in run.checked.problems, run.checked.problems
    assert run.partial
    line = next(p for p in run.problems if p.startswith(f"metadata {key}: "))
    assert "\n" not in line
    if key == "log_format_version":  # no format known: no episodes or budget to trust
        with pytest.raises(LogError, match="a log of format unknown: the analysis needs") as err:
            analyze_run(run)
        assert err.value.path == str(path)
    elif key in ANALYSIS_KEYS:
        with pytest.raises(LogError, match=f"damaged metadata: .*{key}: ") as err:
            analyze_run(run)
        assert err.value.path == str(path)
    else:
        a = analyze_run(run)  # the rest of the log is analyzed
        assert a.summary["partial"] and key in a.summary["problems"]
        assert a.bounces["bounce"].count() >= 1
    assert f"damaged:    metadata {key}: " in describe(path)
    diff = diff_logs(load_log(intact), run)
    assert diff.equal == (key in DEFAULT_IGNORED_META), diff.report()
    assert write_recording([run], tmp_path / "odd.rrd").stat().st_size > 0


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("description", "ü" * 100_000),
        ("experiment", ""),
        ("source", "/a path/with spaces.toml"),
        ("reason", ""),
        ("sweep", json.dumps({"ball.pos": [0, 0, 1], "ümlaut": "x"})),
        ("warnings", "[]"),
        ("plane_z", ""),  # no plane
        ("gravity", "[0, 0, 0]"),
        ("timestep_s", "0.001"),
        ("steps", "301"),
    ],
)
def test_unusual_but_valid_values_are_accepted(tmp_path, records, key, value):
    run = load_log(rewrite(records, tmp_path / "ok.mcap", meta={key: value}))
    assert key not in run.checked.problems, run.checked.problems


# ---------------------------------------------------------------------------------------------
# metadata that the channels contradict


CONTRADICTIONS = {
    "renamed body": ({"topics": {"/bodies/ball/state": "/bodies/ball2/state"}}, "bodies"),
    "body without channel": (
        {
            "meta": {
                "bodies": '[{"name": "ball", "mass": 1.0, "inertia": [0.004, 0.004, 0.004],'
                ' "radius": 0.1}, {"name": "ghost", "mass": 1.0, "inertia": [1, 1, 1],'
                ' "radius": 0.1}]'
            }
        },
        "bodies",
    ),
    "timestep that does not fit the times": ({"meta": {"timestep_s": "0.0007"}}, "timestep_s"),
    "logging stride that does not fit": ({"meta": {"log_every": "3"}}, "log_every"),
    "steps before the last row": ({"meta": {"steps": "100"}}, "steps"),
    "sweep index beyond the sweep": (
        {"meta": {"sweep_index": "4", "sweep_size": "4"}},
        "sweep_index",
    ),
}


@pytest.mark.parametrize("case", list(CONTRADICTIONS))
def test_metadata_contradicted_by_the_channels(tmp_path, records, intact, case):
    change, key = CONTRADICTIONS[case]
    path = rewrite(records, tmp_path / "odd.mcap", **change)
    run = load_log(path)
    assert key in run.checked.problems, run.checked.problems
    if key in ANALYSIS_KEYS:
        with pytest.raises(LogError, match=f"damaged metadata: .*{key}: "):
            analyze_run(run)
    else:
        assert analyze_run(run).summary["partial"]
    assert write_recording([run], tmp_path / "odd.rrd").stat().st_size > 0
    if key != "log_every":  # info reads no rows: it sees the last time, not the stride
        assert f"damaged:    metadata {key}: " in describe(path)


CONFLICTS = {  # a key, the value a second record of its name gives it
    "bodies": '[{"name": "ball", "mass": 5.0, "inertia": [0.02, 0.02, 0.02], "radius": 0.1}]',
    "gravity": "[0, 0, -1.62]",
    "timestep_s": "0.002",
    "outcome": "unstable",
    "experiment": "another",
    "description": "said twice",
}


@pytest.mark.parametrize("key", list(CONFLICTS))
def test_two_records_that_disagree(tmp_path, records, intact, key):
    """A second metadata record of one name that gives a key another value: the key is a
    problem naming both values (neither wins), blocking where the analysis needs it; a second
    record that agrees is harmless."""
    path = rewrite(records, tmp_path / "twice.mcap", again={key: CONFLICTS[key]})
    run = load_log(path)
    problem = run.checked.problems.get(key, "")
    assert problem.startswith("two impactlab.") and CONFLICTS[key] in problem, problem
    assert key not in run.checked.values
    if key in ANALYSIS_KEYS:
        with pytest.raises(LogError, match=f"damaged metadata: .*{key}: two impactlab"):
            analyze_run(run)
    else:
        assert analyze_run(run).summary["partial"]
    assert f"damaged:    metadata {key}: two impactlab." in describe(path)
    same = load_log(rewrite(records, tmp_path / "same.mcap", again={}))
    assert not same.partial and not same.checked.problems


@pytest.mark.parametrize("topic", ["/bodies/ball/state", "/bodies/ball/clearance", "/energy"])
def test_every_message_of_a_channel_twice(tmp_path, records, intact, topic):
    """A log whose messages on a per-step channel are each written twice is not read as the
    intact one: the channel is named, the first message at each time is kept, the analysis is
    partial and diff, comparing what is kept, warns that B is damaged."""
    path = rewrite(records, tmp_path / "twice.mcap", twice={topic})
    run, whole = load_log(path), load_log(intact)
    (problem,) = [p for p in run.problems if "already has a message at" in p]
    count = sum(1 for c, _ in records[3] if c.topic == topic)
    assert problem.startswith(f"damaged: {topic}: {count:,} messages"), problem
    assert run.bodies["ball"].equals(whole.bodies["ball"]) and run.energy.equals(whole.energy)
    assert analyze_run(run).summary["partial"]
    assert f"B is incomplete: {problem}" in diff_logs(whole, run).notes


@pytest.mark.slow
@pytest.mark.parametrize("which", ["later half", "all"])
def test_log_time_beyond_int64(tmp_path, capsys, records, intact, which):
    """log_time is unsigned 64-bit in MCAP: messages at >= 2^63 ns are skipped and named."""
    cut = 150_000_000 if which == "later half" else -1
    path = rewrite(records, tmp_path / "late.mcap", time=lambda t: t + 2**63 if t > cut else t)
    run = load_log(path)
    if which == "all":  # the metadata, and no row: nothing to analyze, nothing crashes
        assert run.partial and run.bodies["ball"].is_empty() and run.energy.is_empty()
        assert analyze_run(run).summary["duration_s"] == 0.0
        return
    assert run.partial and any("2^63" in p for p in run.problems)
    ball = run.bodies["ball"]
    assert ball.height == 151 and ball["t_ns"].max() == 150_000_000
    assert analyze_run(run).summary["partial"]
    for argv, code in (
        (["analyze", str(path), "-o", str(tmp_path / "out")], 0),
        (["diff", str(intact), str(path)], 1),
        (["replay", str(path), "-o", str(tmp_path / "rrd")], 0),
        (["info", str(path)], 0),
    ):
        assert main(argv) == code, argv
        err = capsys.readouterr().err
        assert "Traceback" not in err
        if argv[0] != "info":
            assert "2^63" in err, err


# ---------------------------------------------------------------------------------------------
# the command line: one line naming the log and the key, the other logs analyzed


@pytest.mark.slow
def test_command_line_names_the_log_and_the_key(tmp_path, capsys, records, intact):
    soft = rewrite(records, tmp_path / "soft.mcap", meta={"sweep_index": "x"})
    hard = rewrite(records, tmp_path / "hard.mcap", meta={"timestep_s": "1e+300"})
    out = tmp_path / "out"
    code = main(["analyze", str(soft), str(hard), str(intact), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 1 and "Traceback" not in err, err
    errors = [line for line in err.splitlines() if line.startswith("impactlab: error:")]
    assert errors == [
        f"impactlab: error: {hard}: damaged metadata: timestep_s: '1e+300' is out of range "
        "(expected: number 1e-09 .. 10 s): cannot analyze"
    ]
    warnings = [line for line in err.splitlines() if line.startswith("impactlab: warning:")]
    assert len(warnings) == 1 and warnings[0].startswith(f"impactlab: warning: {soft}: ")
    assert "metadata sweep_index: 'x' is not a whole number" in warnings[0]
    runs = pl.read_parquet(out / "runs.parquet")
    assert dict(zip(runs["file"], runs["partial"], strict=True)) == {
        str(soft): True,
        str(intact): False,
    }
    assert "timestep_s" in (out / "report.md").read_text()  # the failed log is listed

    for argv, code in (
        (["diff", str(intact), str(hard)], 1),
        (["replay", str(hard), "-o", str(tmp_path / "rrd")], 0),
        (["info", str(hard)], 0),
    ):
        assert main(argv) == code
        captured = capsys.readouterr()
        assert "Traceback" not in captured.err
        assert "timestep_s" in captured.err + captured.out
    assert np.all(np.isfinite(load_log(hard).bodies["ball"]["z"].to_numpy()))
