"""`impactlab calibrate`: calibrated contacts recorded by the recorder, measured by the analysis.

The shipped calibration experiment is recorded once per module, cut to targets {0.2, 0.5, 0.9,
0.99}: a ball hitting the floor once (gravity) and two balls head on (zero gravity), at 1, 3
and 10 m/s, masses 0.1 and 10 kg (the second ball 1 kg). Beside it, drops of the test's own
bounce several times (first impact 3 m/s) with several targets, radii, masses, speed ranges
(the default from the experiment, wide or limited by the bounce count, and an explicit narrow
one) and integrators: every bounce in the contact's speed range is checked against the
target, every bounce below it against the designer's prediction.

Under gravity e is lower than at the force's release by about 2 zeta g / (w0 v) (the ball is
still inside the floor when the force lets go); the designer calibrates that out over the
range, `test_the_gravity_shift_is_compensated` checks it where the shift is largest (e = 0.2
at 1 m/s: 0.02).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace

import polars as pl
import pytest
from paths import EXPERIMENTS
from specs import drop

from impactlab.calibrate.job import run_calibration
from impactlab.calibrate.table import calibration_table
from impactlab.cli import main
from impactlab.contact import RestitutionCurve, contact_params
from impactlab.errors import SpecError
from impactlab.physics import collision_after
from impactlab.record import plan

SHIPPED = [EXPERIMENTS / "calibration" / f"{name}.toml" for name in ("impacts", "collisions")]
TARGETS = (0.2, 0.5, 0.9, 0.99)
E_TOL = 0.005
PEN_FRAC = 0.02
G = 9.81
LADDER = (5e-5, 2e-5, 1e-5, 5e-6, 2e-6, 1e-6)
FIRST_MPS = 3.0
GAP_M = 1.3e-4


def _drop(e: float, radius: float, mass: float, *, low=None, integrator="Euler", bounces=None):
    """A ball reaching the floor at 3 m/s and bouncing until about 0.15 m/s (at most 8), at
    the largest timestep of LADDER the recorder accepts; `low`: the contact's range
    [low, first impact] instead of the experiment's."""
    n = bounces or min(8, max(2, math.ceil(math.log(0.15 / FIRST_MPS) / math.log(e)) + 1))
    fast = min(e + E_TOL, 1.0)  # the longest flights
    flights = sum(2 * FIRST_MPS * fast**k / G for k in range(1, n)) + FIRST_MPS * fast**n / G
    first = math.sqrt(FIRST_MPS**2 + 2 * G * GAP_M)
    contact = {"restitution": e} | ({} if low is None else {"speed_range": [low, first]})
    name = f"drop_e{e:g}_r{radius:g}_m{mass:g}_{'d' if low is None else low}_{integrator}"
    for dt in LADDER:
        doc = drop(
            name.replace(".", "p"),
            z=radius + GAP_M,
            radius=radius,
            mass=mass,
            vel=[0.0, 0.0, -FIRST_MPS],
            timestep=dt,
            integrator=integrator,
            contact=contact,
            max_time=flights + 0.05,
            bounces=n,
            every=10,
        )
        try:
            plan(doc)
        except SpecError as exc:
            if "timestep" not in str(exc):
                raise
            continue
        return doc
    raise AssertionError(f"no timestep for {name}")


DROPS = (
    dict(e=0.5, radius=0.1, mass=1.0),  # default range 0.5..3 m/s (the floor): bounces below it
    dict(e=0.9, radius=0.05, mass=0.1, bounces=5),  # default range limited by the bounce count
    dict(e=0.8, radius=0.2, mass=10.0, low=1.5),  # an explicit narrow range
    dict(e=0.3, radius=0.3, mass=7.7),  # large radius, low e
    dict(e=0.97, radius=0.03, mass=0.13, bounces=4),  # small radius, high e
    dict(e=0.7, radius=0.1, mass=1.0, integrator="RK4"),
    dict(e=0.6, radius=0.1, mass=2.0, integrator="implicitfast"),
)


@pytest.fixture(scope="module")
def shipped(tmp_path_factory):
    """The shipped impacts and collisions cut to TARGETS: the result, and each run's sweep."""
    out = tmp_path_factory.mktemp("calibrate") / "shipped"
    result = run_calibration(out, specs=SHIPPED, targets=TARGETS, echo=lambda _: None)
    runs = plan(SHIPPED, overrides=[f"contact.restitution={list(TARGETS)}"])
    info = {r.info.run_id: (r.info.sweep, r.pairs[0].params) for r in runs}
    return result, info


@pytest.fixture(scope="module")
def drops(tmp_path_factory):
    out = tmp_path_factory.mktemp("calibrate") / "drops"
    docs = [_drop(**case) for case in DROPS]
    result = run_calibration(out, specs=docs, echo=lambda _: None)
    params = {r.info.run_id: r.pairs[0].params for r in plan(docs)}
    table = result.table.with_columns(
        pl.col("run_id")
        .replace_strict({k: p.integrator for k, p in params.items()})
        .alias("integrator")
    )
    return result, table, docs


def _kind(table: pl.DataFrame, experiment: str) -> pl.DataFrame:
    return table.filter(pl.col("run_id").str.starts_with(f"{experiment}-"))


@pytest.mark.slow
def test_every_impact_of_the_shipped_experiment_meets_its_target(shipped):
    result, info = shipped
    table = result.table
    assert result.exit_code == 0, result.failures.to_dicts()
    assert _kind(table, "calibration_impacts").height == 24
    assert _kind(table, "calibration_collisions").height == 24
    assert table["in_range"].all()  # one impact each, at the speed its contact was designed for
    assert (table["error"].abs() <= E_TOL).all()
    assert (table["penetration_m"] <= PEN_FRAC * 0.1).all()
    # the impact speed is the requested one, to a step of gravity
    for row in _kind(table, "calibration_impacts").iter_rows(named=True):
        sweep, params = info[row["run_id"]]
        v = -sweep["bodies.ball.vel"][2]
        assert row["speed_mps"] == pytest.approx(math.sqrt(v**2 + 2 * G * 1.3e-4), abs=G * 5e-6)
        assert params.speed_range_mps[0] == params.speed_range_mps[1]


@pytest.mark.slow
def test_the_gravity_shift_is_compensated(shipped):
    """Gravity lowers e by about 2 zeta g / (w0 v), up to 4x the tolerance here; the designer
    calibrates it out at the design speed."""
    result, info = shipped
    plane = _kind(result.table, "calibration_impacts").with_columns(
        pl.col("run_id")
        .replace_strict({k: p.gravity_shift for k, (_, p) in info.items()})
        .alias("shift")
    )
    shifted = plane.filter(pl.col("shift") < -E_TOL)
    assert shifted.height >= 2 and shifted["shift"].min() < -0.018  # e = 0.2 at 1 m/s
    assert shifted["error"].abs().max() <= 0.002


@pytest.mark.slow
def test_e_does_not_depend_on_the_mass(shipped):
    result, info = shipped
    mass = {k: s.get("bodies.ball.mass", s.get("bodies.ball1.mass")) for k, (s, _) in info.items()}
    keyed = result.table.with_columns(
        pl.col("run_id").replace_strict(mass).alias("mass"),
        pl.col("run_id").str.replace(r"\.mass=[0-9.]+-[0-9a-f]+$", "").alias("point"),
    )
    assert keyed["mass"].n_unique() == 2
    spread = keyed.group_by("point").agg((pl.col("e").max() - pl.col("e").min()).alias("d"))
    assert spread.height == 24 and spread["d"].max() < 1e-9


@pytest.mark.slow
def test_collisions_give_the_1d_outcome_of_the_target_and_keep_momentum(shipped):
    result, _ = shipped
    collisions = pl.read_parquet(result.out_dir / "results" / "collisions.parquet")
    targets = dict(_kind(result.table, "calibration_collisions").select("run_id", "target").rows())
    assert collisions.height == 24 and set(collisions["run_id"]) == set(targets)
    for c in collisions.iter_rows(named=True):
        v1, v2 = c["v1n_before_mps"], c["v2n_before_mps"]
        closing = v1 - v2
        assert closing == pytest.approx(round(closing), rel=1e-9)  # 1, 3 or 10 m/s
        t1, t2 = collision_after(c["m1_kg"], c["m2_kg"], v1, v2, targets[c["run_id"]])
        assert abs(c["v1n_after_mps"] - t1) <= 0.005 * closing
        assert abs(c["v2n_after_mps"] - t2) <= 0.005 * closing
        assert c["momentum_rel_change"] <= 1e-9
        assert c["target_e"] == targets[c["run_id"]]  # the analysis' own: in the range


@pytest.mark.slow
def test_every_bounce_in_range_meets_the_target(drops):
    _, table, docs = drops
    assert set(table["run_id"].str.extract(r"^(.*?)-")) == {d["name"] for d in docs}
    for run_id, rows in table.group_by("run_id"):
        rows = rows.sort("impact")
        assert rows["impact"].to_list() == list(range(1, rows.height + 1))  # none missing
        inside = rows.filter(pl.col("in_range"))
        assert inside.height >= 2, run_id
        assert inside["error"].abs().max() <= E_TOL, inside.select(
            "impact", "speed_mps", "error"
        ).rows()
        assert inside["penetration_m"].max() <= inside["penetration_bound_m"].max() * 1.01
    # the drops differ in what matters: radius, mass, target, range width, integrator
    params = {r.info.run_id: r.pairs[0].params for r in plan(docs)}
    widths = [p.speed_range_mps[1] / p.speed_range_mps[0] for p in params.values()]
    assert min(widths) < 2.5 and max(widths) >= 5.9
    assert set(table["integrator"]) == {"Euler", "RK4", "implicitfast"}
    assert len({d["bodies"]["ball"]["radius"] for d in docs}) >= 4
    assert len({d["bodies"]["ball"]["mass"] for d in docs}) >= 4


@pytest.mark.slow
def test_the_default_range_covers_every_bounce_above_the_floor(drops):
    """The default range (from the stop rule's bounces, floored at 0.5 m/s) holds every
    logged bounce above 0.5 m/s."""
    _, table, docs = drops
    default = [d["name"] for d in docs if "speed_range" not in d["contact"]]
    rows = table.filter(pl.col("run_id").str.extract(r"^(.*?)-").is_in(default))
    assert len(default) == 6
    above = rows.filter(pl.col("speed_mps") >= 0.5)
    assert above["in_range"].all() and (above["error"].abs() <= E_TOL).all()
    assert rows.filter(pl.col("speed_mps") < 0.5).height >= 2
    assert not rows.filter(pl.col("speed_mps") < 0.49)["in_range"].any()


@pytest.mark.slow
def test_below_the_range_e_is_where_the_designer_predicts(drops):
    """Below the range gravity lowers e, and the designer's step emulation predicts it: the
    measurement lies in the predicted band, at the mean to a few 1e-3."""
    result, table, _ = drops
    assert result.exit_code == 0, result.failures.to_dicts()
    below = table.filter(~pl.col("in_range"))
    assert below.height >= 5 and below["ok"].all()
    assert (below["e"] - below["e_predicted"]).abs().max() <= 0.003
    # e = 0.5 well below its range (0.2 m/s and less): visibly low, as predicted
    low = below.filter((pl.col("target") == 0.5) & (pl.col("speed_mps") < 0.2))
    assert low.height >= 1 and (low["error"] < -E_TOL).all()


@pytest.mark.slow
def test_calibrate_twice_into_one_folder(tmp_path, capsys):
    """`impactlab calibrate` (the shipped experiment, one target) run again into the same
    folder reuses the logs and writes the same report and table."""
    from polars.testing import assert_frame_equal

    out = tmp_path / "cal"
    args = ["calibrate", "--targets", "0.9", "-o", str(out)]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "impacts of calibrated pairs: every impact meets its bound" in printed
    first = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    logs = {p: p.stat().st_mtime_ns for p in out.glob("logs/*.mcap")}
    assert len(logs) == 6 + 6 + 3
    assert main(args) == 0
    assert {p: p.stat().st_mtime_ns for p in out.glob("logs/*.mcap")} == logs  # reused
    report = (out / "results" / "report.md").read_text()
    assert "## Calibration: e against its target at every impact" in report
    assert report == first[Path("results/report.md")].decode()
    table = pl.read_parquet(out / "results" / "calibration.parquet")
    assert table.height == 6 + 6 + 3 * 6 and table["ok"].all()
    assert_frame_equal(table, pl.read_parquet(first[Path("results/calibration.parquet")]))


def _params(e: float = 0.8):
    return contact_params(e, radius_m=0.1, impact_speed_mps=2.0, timestep_s=1e-5)


def _bounces(rows: list[tuple]) -> pl.DataFrame:
    schema = ["run_id", "body", "surface", "bounce", "v_in_mps", "e_velocity", "target_e"]
    frame = pl.DataFrame(rows, schema=schema, orient="row")
    return frame.with_columns(
        pl.lit(True).alias("complete"), pl.lit(1e-3).alias("max_penetration_m")
    )


def test_each_impact_is_judged_by_its_bound():
    """In its range within the tolerance; outside it within the predicted band; a pair
    without an impact is a failing row of its own (no data from a simulation here)."""
    p = _params()
    runs = [
        SimpleNamespace(
            info=SimpleNamespace(run_id=r),
            pairs=[SimpleNamespace(geom1="plane", geom2="ball", params=p)],
        )
        for r in ("a", "b")
    ]
    bounces = _bounces(
        [
            ("a", "ball", "plane", 1, -2.0, 0.803, 0.8),  # in range, within 0.005
            ("a", "ball", "plane", 2, -1.6, 0.81, 0.8),  # in range, 0.01 off
            ("a", "ball", "plane", 3, -0.2, 0.70, None),  # below the range, far from the band
            ("a", "ball", "plane", 4, -0.2, 0.7945, None),  # below the range, in the band
        ]
    )
    table = calibration_table(runs, bounces, pl.DataFrame())
    assert table["ok"].to_list() == [True, False, False, True, False]
    assert "> 0.005" in table["note"][1] and "outside the predicted" in table["note"][2]
    assert table.row(4, named=True)["run_id"] == "b"
    assert table["note"][4] == "no complete impact in the log" and table["e"][4] is None
    deep = bounces.head(1).with_columns(pl.lit(1.0).alias("max_penetration_m"))
    (row,) = calibration_table(runs[:1], deep, pl.DataFrame()).rows(named=True)
    assert not row["ok"] and row["note"].startswith("penetration 1 m")


def test_an_impact_of_an_e_v_target_is_judged_at_its_speed():
    """A pair whose target is a curve: the analysis' target_e (the curve at the impact's
    speed) is what e is measured against, not one number (the params here are the constant
    design with a curve attached: the table's wiring, not a design)."""
    p = dataclasses.replace(_params(), curve=RestitutionCurve.of([1.0, 3.0], [0.85, 0.75]))
    runs = [
        SimpleNamespace(
            info=SimpleNamespace(run_id="a"),
            pairs=[SimpleNamespace(geom1="plane", geom2="ball", params=p)],
        )
    ]
    bounces = _bounces(
        [
            ("a", "ball", "plane", 1, -1.0, 0.851, 0.85),  # 0.051 from 0.8, 0.001 from e(v)
            ("a", "ball", "plane", 2, -2.0, 0.80, 0.80),
            ("a", "ball", "plane", 3, -3.0, 0.80, 0.75),  # 0.05 off the curve
        ]
    )
    table = calibration_table(runs, bounces, pl.DataFrame())
    assert table["error"].to_list() == pytest.approx([0.001, 0.0, 0.05])
    assert table["ok"].to_list() == [True, True, False]


def test_command_line_options():
    import argparse

    from impactlab.cli.calibrate import register

    parser = argparse.ArgumentParser()
    register(parser.add_subparsers())
    args = parser.parse_args(["calibrate", "--targets", "0.3", "0.7", "-o", "x"])
    assert args.targets == [0.3, 0.7] and str(args.out) == "x" and not args.discard_logs


@pytest.mark.parametrize(
    ("targets", "words"),
    [((0.8, 0.8), "lists 0.8 twice"), ((2.0,), "2.0 is out of range"), ((0.05,), "out of range")],
)
def test_bad_targets_are_refused_before_anything_is_written(tmp_path, targets, words):
    with pytest.raises(SpecError, match=words) as info:
        run_calibration(tmp_path / "cal", targets=targets, echo=lambda _: None)
    assert info.value.source == "--targets"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("existed", [False, True], ids=["new folder", "existing folder"])
def test_a_failed_calibration_leaves_no_folder_it_created(tmp_path, monkeypatch, existed):
    """A job that fails after writing (as an install without the restitution tables did)
    removes the output folder it created, and leaves a folder that was there alone."""
    import impactlab.calibrate.job as job

    out = tmp_path / "calibration"
    if existed:
        out.mkdir()
        (out / "mine.txt").write_text("kept")

    def broken(runs, out_dir, **kwargs):
        (out_dir / "logs").mkdir()
        (out_dir / "logs" / "a.mcap").write_text("")
        raise FileNotFoundError("restitution_table.json")

    monkeypatch.setattr(job, "_calibrate", broken)
    with pytest.raises(FileNotFoundError):
        run_calibration(out, echo=lambda _: None)
    assert out.exists() == existed
    if existed:
        assert (out / "mine.txt").read_text() == "kept"
