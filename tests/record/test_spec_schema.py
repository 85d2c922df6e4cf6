"""The spec schema, tested by class: every field with every wrong type (the cases are generated
from the schema itself), tables where values belong, values where tables belong, absurd sizes.
Each gives one line naming the file and the dotted field, exit code 2, and writes nothing."""

from __future__ import annotations

from pathlib import Path

import pytest
from specs import drop, toml

from impactlab.cli import main
from impactlab.record.schema import Logging, PairContact, SpecDocument, Stop
from impactlab.record.sweep import load_runs

GOOD = toml(drop(max_time=0.01))

# one TOML value of each JSON type
SAMPLES = {
    "string": '"text"',
    "boolean": "true",
    "integer": "7",
    "number": "1.5",
    "array": "[1.0, 2.0]",
    "object": "{ a = 1 }",
}


def _types(node: dict, defs: dict) -> set[str]:
    """The JSON types a schema node accepts."""
    if "$ref" in node:
        return {"object"}
    if "anyOf" in node:
        return set().union(*(_types(n, defs) for n in node["anyOf"]))
    if "type" in node:
        return {node["type"]}
    if "enum" in node:
        return {"integer" if isinstance(v, int) else "string" for v in node["enum"]}
    raise AssertionError(f"unknown schema node {node}")


def schema_fields() -> list[tuple[str, set[str]]]:
    """Every value of a spec as (dotted path, JSON types it accepts), read from the schema."""
    schema = SpecDocument.model_json_schema()
    defs = schema["$defs"]
    out = []
    for name, node in schema["properties"].items():
        if name == "bodies":
            section = defs[node["additionalProperties"]["$ref"].split("/")[-1]]
            out += [(f"bodies.ball.{k}", _types(v, defs)) for k, v in section["properties"].items()]
        elif "$ref" in node:
            section = defs[node["$ref"].split("/")[-1]]
            out += [(f"{name}.{k}", _types(v, defs)) for k, v in section["properties"].items()]
        else:
            out.append((name, _types(node, defs)))
    return out


def _accepts(types: set[str], sample: str) -> bool:
    return sample in types or (sample == "integer" and "number" in types)


WRONG_TYPES = [
    (path, SAMPLES[sample])
    for path, types in schema_fields()
    for sample in SAMPLES
    if not _accepts(types, sample)
]


def test_the_generated_cases_cover_every_field():
    paths = {path for path, _ in WRONG_TYPES}
    assert len(paths) == len(schema_fields()) == 34  # every field has a wrong type to try
    assert {"options.gravity", "contact.pairs", "bodies.ball.rgba", "logging.every"} <= paths
    assert len(WRONG_TYPES) > 120


def one_line(capsys, code: int, out: Path) -> str:
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("impactlab: error: ") and "Traceback" not in err
    assert not out.exists()
    return lines[0]


@pytest.mark.parametrize(("path", "value"), WRONG_TYPES)
def test_every_field_with_every_wrong_type(tmp_path, capsys, path, value):
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD)
    out = tmp_path / "out"
    line = one_line(
        capsys, main(["record", str(spec), "-o", str(out), "--set", f"{path}={value}"]), out
    )
    assert f"spec.toml: {path}" in line, line


@pytest.mark.parametrize("path", [p for p, _ in schema_fields()])
def test_every_field_with_a_wrong_type_in_the_file(tmp_path, capsys, path):
    """The same class in the spec file itself: a table where the value belongs."""
    section, _, key = path.rpartition(".")
    text = GOOD if section else GOOD.replace('name = "t"', "")
    table = f"[{section}]" if section else None
    given = [line for line in text.splitlines() if line.startswith(f"{key} =")]
    if given and (section or key == "name"):
        text = text.replace(given[0], f"{key} = {{ a = 1 }}", 1)
    elif table and table in text:
        text = text.replace(table, f"{table}\n{key} = {{ a = 1 }}", 1)
    elif table:
        text += f"{table}\n{key} = {{ a = 1 }}\n"
    else:
        text = f"{key} = {{ a = 1 }}\n" + text
    spec = tmp_path / "spec.toml"
    spec.write_text(text)
    out = tmp_path / "out"
    line = one_line(capsys, main(["record", str(spec), "-o", str(out)]), out)
    assert f"spec.toml: {path}" in line, line


TABLES = ["options", "contact", "plane", "stop", "logging", "bodies", "bodies.ball", "ball"]


@pytest.mark.parametrize("value", ["{}", "{ condim = 1 }", "1", "[]", "true", '"x"'])
@pytest.mark.parametrize("table", TABLES)
def test_a_value_where_a_table_belongs(tmp_path, capsys, table, value):
    """The issue's `--set 'contact={}'`, `options=1`, `ball={}`, `logging=[]`, `plane=true`."""
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD)
    out = tmp_path / "out"
    line = one_line(
        capsys, main(["record", str(spec), "-o", str(out), "--set", f"{table}={value}"]), out
    )
    assert f"--set: {table}: is a table; set its fields instead" in line


@pytest.mark.parametrize("table", TABLES)
def test_a_sweep_over_a_table(tmp_path, capsys, table):
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD + f'[sweep]\n"{table}" = [{{ condim = 1 }}]\n')
    out = tmp_path / "out"
    line = one_line(capsys, main(["record", str(spec), "-o", str(out)]), out)
    assert "sweep: " in line and "is a table" in line


ABSURD = [
    ("name", '"' + "n" * 100_000 + '"', "must be a name of 1 to 64"),
    ("bodies.ball.pos", "[" + ", ".join(["0.5"] * 1_000_000) + "]", "must be a list of 3 numbers"),
    ("logging.every", "10000000000000000000000", "must be <= 1e+09"),
    ("stop.bounces", "-10000000000000000000000", "must be >= 1"),
    ("contact.condim", "10000000000000000000000", "must be 1, 3, 4 or 6"),
    ("stop.max_time", "1e300", "must be <= 1e+09"),
    ("options.timestep", "1e-12", "must be >= 1e-09 s (log times are whole nanoseconds)"),
    ("options.timestep", "inf", "must be finite"),
    ("bodies.ball.mass", "nan", "must be finite"),
    ("bodies.ball.mass", "1e-300", "with radius 0.1 m its inertia is 4e-303"),
    ("description", '"' + "d" * 100_000 + '"', "must be at most 10000 characters"),
]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("path", "value", "words"), ABSURD, ids=[f"{a[0]}-{a[2][:20]}" for a in ABSURD]
)
def test_absurd_sizes(tmp_path, capsys, path, value, words):
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD)
    out = tmp_path / "out"
    line = one_line(
        capsys, main(["record", str(spec), "-o", str(out), "--set", f"{path}={value}"]), out
    )
    assert f"{path}: {words}" in line, line
    assert len(line) < 400  # the value is cut, not printed whole


def test_nesting_too_deep_in_a_file_and_an_override(tmp_path, capsys):
    deep = "[" * 3000 + "]" * 3000
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD + f"x = {deep}\n")
    out = tmp_path / "out"
    assert "spec.toml: invalid TOML: nested too deeply" in one_line(
        capsys, main(["record", str(spec), "-o", str(out)]), out
    )
    spec.write_text(GOOD)
    line = one_line(
        capsys, main(["record", str(spec), "-o", str(out), "--set", f"ball.pos={deep}"]), out
    )
    assert "ball.pos: invalid TOML: nested too deeply" in line


def test_many_bodies_and_long_names(tmp_path, capsys):
    bodies = "".join(
        f"[bodies.b{i}]\nradius = 0.1\nmass = 1.0\npos = [{i}.0, 0.0, 1.0]\n" for i in range(65)
    )
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD.split("[bodies.ball]")[0] + bodies + "[stop]\nmax_time = 0.01\n")
    out = tmp_path / "out"
    assert "bodies: must have at most 64 entries" in one_line(
        capsys, main(["record", str(spec), "-o", str(out)]), out
    )


def test_a_sweep_point_listed_twice_names_the_file_and_field(tmp_path, capsys):
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD + '[sweep]\n"ball.mass" = [1.0, 2.0, 1]\n')
    out = tmp_path / "out"
    line = one_line(capsys, main(["record", str(spec), "-o", str(out)]), out)
    assert line == f"impactlab: error: {spec}: sweep.bodies.ball.mass: lists 1 twice"
    line = one_line(
        capsys,
        main(["record", str(spec), str(spec), "-o", str(out), "--set", "ball.mass=[1.0]"]),
        out,
    )
    assert f"{spec}: sweep point (bodies.ball.mass = 1.0) is the same run as" in line


def test_overriding_a_swept_vector_with_one_value_is_one_run(tmp_path):
    """`--set ball.pos=[0, 0, 1]` on a spec that sweeps ball.pos is one run at that position
    (it used to become a sweep over 0, 0 and 1); a list of positions is a sweep of them."""
    spec = tmp_path / "spec.toml"
    spec.write_text(
        GOOD + '[sweep]\n"ball.pos" = [[0.0, 0.0, 1.0], [0.0, 0.0, 2.0], [0.0, 0.0, 3.0]]\n'
    )
    (run,) = load_runs(spec, ["ball.pos=[0, 0, 1.5]"])
    assert run.bodies[0].pos == (0.0, 0.0, 1.5)
    runs = load_runs(spec, ["ball.pos=[[0, 0, 1.5], [0, 0, 2.5]]"])
    assert [r.bodies[0].pos[2] for r in runs] == [1.5, 2.5]
    assert len(load_runs(spec)) == 3


def test_overriding_a_swept_scalar(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD + '[sweep]\n"ball.mass" = [1.0, 2.0]\n')
    assert [r.bodies[0].mass for r in load_runs(spec, ["ball.mass=5"])] == [5.0]
    assert [r.bodies[0].mass for r in load_runs(spec, ["ball.mass=[3, 4]"])] == [3.0, 4.0]


def test_the_document_and_its_hash_are_unchanged_by_the_schema(tmp_path):
    """The resolved document (hashed, and logged) is the TOML content over the defaults, as
    before the schema: the golden logs' spec hashes stay valid."""
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD)
    (run,) = load_runs(spec)
    assert run.document["bodies"]["ball"] == {
        "radius": 0.1,
        "mass": 1.0,
        "pos": [0.0, 0.0, 1.0],
        "vel": [0.0, 0.0, 0.0],
        "angvel": [0.0, 0.0, 0.0],
        "rgba": None,
    }
    assert run.document["contact"]["solimp"] == [0.9, 0.95, 0.001, 0.5, 2.0]
    assert run.document["stop"] == {
        "max_time": 0.01,
        "bounces": None,
        "at_rest": False,
        "rest_speed": 1e-3,
        "rest_time": 0.05,
        "separation": None,
        "max_energy_gain": 0.1,
        "max_penetration": 1.0,
    }
    # the hash the same spec had before the schema (commit 718ee37)
    assert run.spec_hash == "d6facaf5a6ecc8dd6e21bf174f4e7708882640e04b727c74a605bc18665cb16e"


def _section_fields(model) -> list[tuple[str, set[str]]]:
    schema = model.model_json_schema()
    return [(k, _types(v, schema.get("$defs", {}))) for k, v in schema["properties"].items()]


PAIR_WRONG_TYPES = [
    (key, SAMPLES[sample])
    for key, types in _section_fields(PairContact)
    for sample in SAMPLES
    if not _accepts(types, sample)
]


@pytest.mark.parametrize(("key", "value"), PAIR_WRONG_TYPES)
def test_every_pair_field_with_every_wrong_type(tmp_path, capsys, key, value):
    """A `[contact.pairs."a/b"]` table takes the calibrated-contact fields of [contact]
    (issue 15), checked by the same declarations."""
    spec = tmp_path / "spec.toml"
    spec.write_text(GOOD + f'[contact.pairs."plane/ball"]\n{key} = {value}\n')
    out = tmp_path / "out"
    line = one_line(capsys, main(["record", str(spec), "-o", str(out)]), out)
    assert f"spec.toml: contact.pairs.plane/ball.{key}: " in line, line


def test_pair_tables_are_checked_as_a_whole(tmp_path, capsys):
    out = tmp_path / "out"
    assert {k for k, _ in PAIR_WRONG_TYPES} == {
        "restitution",
        "speed_range",
        "duration",
        "max_penetration",
        "duration_speed",
    }
    cases = [
        (
            '"ball/plane" = { restitution = 0.5 }\n"plane/ball" = { restitution = 0.6 }',
            "names the same pair as 'ball/plane'",
        ),
        ('"ball/plane" = {}', "must be a table with some of restitution, speed_range"),
        ('"ball" = { restitution = 0.5 }', "pair keys are two geom names joined by /"),
        ('"ball/plane" = { speed_range = [2.0, 1.0] }', "need 0 < v_lo <= v_hi (m/s)"),
    ]
    for table, words in cases:
        spec = tmp_path / "spec.toml"
        spec.write_text(GOOD + f"[contact.pairs]\n{table}\n")
        line = one_line(capsys, main(["record", str(spec), "-o", str(out)]), out)
        assert words in line and "spec.toml: contact.pairs" in line, line


MJCF = '<mujoco><worldbody><body><freejoint/><geom size="0.1"/></body></worldbody></mujoco>'
MJCF_WRONG_TYPES = [
    (f"{section}.{key}", SAMPLES[sample])
    for section, model in (("stop", Stop), ("logging", Logging))
    for key, types in _section_fields(model)
    for sample in SAMPLES
    if not _accepts(types, sample)
]


@pytest.mark.parametrize(("path", "value"), MJCF_WRONG_TYPES)
def test_every_mjcf_run_option_with_every_wrong_type(tmp_path, capsys, path, value):
    """An MJCF model's run options (issue 14) are the spec's [stop] and [logging] fields,
    validated by the same schema."""
    model = tmp_path / "m.xml"
    model.write_text(MJCF)
    out = tmp_path / "out"
    duration = [] if path == "stop.max_time" else ["--duration", "1"]
    args = ["record", str(model), *duration, "-o", str(out), "--set", f"{path}={value}"]
    line = one_line(capsys, main(args), out)
    assert f"m.xml: {path}: " in line, line


def test_mjcf_run_options_out_of_range(tmp_path, capsys):
    model = tmp_path / "m.xml"
    model.write_text(MJCF)
    out = tmp_path / "out"
    for override, words in [
        ("logging.every=0", "logging.every: must be >= 1, got 0"),
        ("stop.max_time=1e12", "stop.max_time: must be <= 1e+09"),
        ("stop.rest_speed=-1", "stop.rest_speed: must be > 0"),
        ("options.timestep=0.001", "--set options.timestep: an MJCF model takes run options"),
        ("stop=1", "stop: is a table; set its fields instead"),
    ]:
        duration = [] if override.startswith("stop.max_time") else ["--duration", "1"]
        args = ["record", str(model), *duration, "-o", str(out), "--set", override]
        line = one_line(capsys, main(args), out)
        assert words in line, line
