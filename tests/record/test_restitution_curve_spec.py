"""A contact's restitution as a table of measured points e(v) (issue 39): every malformed table,
global or a pair's, is one line naming the field, exit code 2, nothing written; a good one is a
`RestitutionCurve` that reaches the designer with its speeds (and `duration_speed`), and a spec
without these keys keeps its document and hash."""

from __future__ import annotations

import dataclasses
import importlib
import math

import pytest
from specs import drop, toml

from impactlab.cli import main
from impactlab.contact import RestitutionCurve, contact_params
from impactlab.errors import SpecError
from impactlab.record.sweep import SpecSweep

contact_pairs = importlib.import_module("impactlab.record.contact_pairs")

CURVE = {"speed_mps": [0.5, 1.0, 2.0, 4.0, 8.0], "e": [0.86, 0.85, 0.82, 0.78, 0.72]}
GLOBAL = "contact.restitution"
PAIR = 'contact.pairs."ball/plane".restitution'

# (TOML value of the restitution, the field named beyond `restitution`, words of the problem)
BAD = [
    ("{ speed_mps = [1.0, 2.0] }", "", "needs both speed_mps and e"),
    ("{ e = [0.8, 0.7] }", "", "needs both speed_mps and e"),
    ("{}", "", "needs both speed_mps and e"),
    ("{ speed_mps = [1.0, 2.0], e = [0.8, 0.7], v = 1 }", ".v", "unknown key"),
    ('{ speed_mps = "1 2", e = [0.8, 0.7] }', ".speed_mps", "a list of finite numbers"),
    ("{ speed_mps = [1.0, 2.0], e = 0.8 }", ".e", "a list of finite numbers"),
    ("{ speed_mps = [1.0, true], e = [0.8, 0.7] }", ".speed_mps", "a list of finite numbers"),
    ('{ speed_mps = [1.0, 2.0], e = [0.8, "0.7"] }', ".e", "a list of finite numbers"),
    ("{ speed_mps = [1.0, nan], e = [0.8, 0.7] }", ".speed_mps", "a list of finite numbers"),
    ("{ speed_mps = [1.0, 2.0], e = [0.8, inf] }", ".e", "a list of finite numbers"),
    ("{ speed_mps = [1.0, [2.0]], e = [0.8, 0.7] }", ".speed_mps", "a list of finite numbers"),
    ("{ speed_mps = [1.0, 2.0], e = [{ a = 1 }, 0.7] }", ".e", "a list of finite numbers"),
    ("{ speed_mps = [1.0, 2.0], e = [0.8, 0.7, 0.6] }", "", "2..64 speeds and as many e"),
    ("{ speed_mps = [1.0], e = [0.8] }", "", "2..64 speeds and as many e"),
    ("{ speed_mps = [], e = [] }", "", "2..64 speeds and as many e"),
    ("{ speed_mps = [2.0, 1.0], e = [0.8, 0.7] }", "", "strictly ascending"),
    ("{ speed_mps = [1.0, 1.0], e = [0.8, 0.7] }", "", "strictly ascending"),
    ("{ speed_mps = [-1.0, 2.0], e = [0.8, 0.7] }", "", "speed_mps[0]"),
    ("{ speed_mps = [0.0, 2.0], e = [0.8, 0.7] }", "", "speed_mps[0]"),
    ("{ speed_mps = [1.0, 1e9], e = [0.8, 0.7] }", "", "speed_mps[1]"),
    ("{ speed_mps = [1.0, 2.0], e = [0.8, 1.5] }", "", "e[1] must be a number in"),
    ("{ speed_mps = [1.0, 2.0], e = [0.8, -0.1] }", "", "e[1] must be a number in"),
    ("{ speed_mps = [1.0, 2.0], e = [0.01, 0.7] }", "", "e[0] must be a number in"),
    ('"0.8"', "", "must be a number or a table"),
    ("true", "", "must be a number or a table"),
    ("[0.8, 0.7]", "", "must be a number or a table"),
    ("nan", "", "must be a number or a table"),
]
HUGE = 100_000


def _record(tmp_path, capsys, text: str) -> str:
    """`impactlab record` of a spec file with `text`: its one error line (exit 2, no output)."""
    spec = tmp_path / "spec.toml"
    spec.write_text(text)
    out = tmp_path / "out"
    code = main(["record", str(spec), "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("impactlab: error: "), err
    assert "Traceback" not in err and not out.exists()
    return lines[0]


def _with(table: str, value: str) -> str:
    base = toml(drop(timestep=1e-5, max_time=0.5, bounces=1))
    if table == GLOBAL:
        return base + f"[contact]\nrestitution = {value}\n"
    return base + f'[contact.pairs."ball/plane"]\nrestitution = {value}\n'


@pytest.mark.parametrize("where", [GLOBAL, PAIR], ids=["global", "pair"])
@pytest.mark.parametrize(("value", "field", "words"), BAD)
def test_every_malformed_curve_is_one_line_naming_its_field(
    tmp_path, capsys, where, value, field, words
):
    line = _record(tmp_path, capsys, _with(where, value))
    named = where.replace('"', "") + field
    assert f"spec.toml: {named}: " in line, line
    assert words in line, line


@pytest.mark.parametrize("where", [GLOBAL, PAIR], ids=["global", "pair"])
def test_an_absurdly_long_curve_is_refused_in_one_short_line(tmp_path, capsys, where):
    speeds = ", ".join(f"{1 + i * 1e-4:.6f}" for i in range(HUGE))
    es = ", ".join(["0.8"] * HUGE)
    line = _record(tmp_path, capsys, _with(where, f"{{ speed_mps = [{speeds}], e = [{es}] }}"))
    assert "2..64 speeds and as many e" in line and len(line) < 300, line[:300]


def _run(document: dict):
    (run,) = SpecSweep.of(document, "<test>").iter_runs()
    return run


def test_a_table_is_a_curve_and_a_spec_without_one_keeps_its_document():
    run = _run(drop(timestep=1e-5, contact={"restitution": CURVE, "duration": 0.004}))
    assert run.contact.restitution == RestitutionCurve.of(CURVE["speed_mps"], CURVE["e"])
    # duration_speed is left out of a document that does not give it: older specs' hashes hold
    assert "duration_speed" not in run.document["contact"]
    given = _run(
        drop(timestep=1e-5, contact={"restitution": CURVE, "duration": 0.004, "duration_speed": 4})
    )
    assert given.document["contact"]["duration_speed"] == 4
    assert given.contact.duration_speed == 4.0 and given.spec_hash != run.spec_hash


@pytest.mark.parametrize(
    ("contact", "field", "words"),
    [
        ({"restitution": CURVE, "duration_speed": 4.0}, "contact.duration_speed", "duration too"),
        (
            {"restitution": 0.8, "pairs": {"ball/plane": {"duration_speed": 4.0}}},
            "contact.pairs.ball/plane.duration_speed",
            "duration too",
        ),
        ({"restitution": CURVE, "duration": 0.004, "duration_speed": 0}, "duration_speed", "> 0"),
        (
            {"restitution": CURVE, "duration": 0.004, "duration_speed": "4"},
            "duration_speed",
            "must be a number",
        ),
    ],
)
def test_duration_speed_needs_a_duration_and_a_speed(contact, field, words):
    with pytest.raises(SpecError, match=words) as info:
        _run(drop(timestep=1e-5, contact=contact))
    assert f"<test>: {field}" in str(info.value) or f"contact.{field}: " in str(info.value)


def test_the_designer_gets_the_curve_its_speeds_and_the_reference_speed(monkeypatch):
    """The wiring only: the designer that takes a curve is the contact package's (its own
    tests); here a stand-in records what it is asked for."""
    asked = []

    def designer(target, **options):
        asked.append((target, dict(options)))
        options.pop("reference_speed_mps", None)
        return dataclasses.replace(contact_params(0.8, **options), curve=target)

    monkeypatch.setattr(contact_pairs, "_calibrated", designer)
    contact = {"restitution": CURVE, "duration": 0.001, "duration_speed": 4.0}
    run = _run(drop(timestep=1e-5, contact=contact, bounces=99, max_time=20.0))
    (pair,) = contact_pairs.calibrated_pairs(run)
    (target, options), *_ = asked
    assert target == pair.params.curve == RestitutionCurve.of(CURVE["speed_mps"], CURVE["e"])
    assert options["reference_speed_mps"] == 4.0 and options["duration_s"] == 0.001
    # the experiment's range stops at the curve's slowest point: no target below it
    v1 = math.sqrt(2 * 9.81 * 0.9)
    assert options["speed_range_mps"] == pytest.approx((0.5, v1))
    # a constant target is asked as before: no reference speed
    asked.clear()
    contact_pairs.calibrated_pairs(_run(drop(timestep=1e-5, contact={"restitution": 0.8})))
    assert "reference_speed_mps" not in asked[0][1] and asked[0][0] == 0.8


@pytest.mark.slow  # the real fit, and its refit at half the timestep (about 10 s)
def test_a_curve_beyond_reach_is_refused_naming_the_restitution_not_the_speeds():
    """A curve the contact cannot follow is the table's fault, whatever range was asked."""
    steep = {"speed_mps": [0.5, 3.0, 10.0], "e": [0.92, 0.75, 0.6]}
    contact = {"restitution": steep, "speed_range": [0.5, 10.0]}
    with pytest.raises(SpecError) as refused:
        contact_pairs.calibrated_pairs(_run(drop(timestep=1e-5, contact=contact)))
    assert refused.value.field == "contact.restitution"
    assert "the nearest reachable curve is e = 0.5:" in str(refused.value)
