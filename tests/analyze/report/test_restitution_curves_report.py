"""Step 2 with a target e(v) and the ball sports' drop tests (issue 39): the sentence is chosen
from the numbers (how much e falls, beside how much its target does; the worst |e - target|),
each drop test a run is (the rule's ball, the rule's height) passes or fails by the measured e
of that impact, and the figure draws the curve and the pass band."""

from __future__ import annotations

import math

import polars as pl
import pytest

from impactlab.analyze.report.blocks import Bullets
from impactlab.analyze.report.context import RunBrief, Tables
from impactlab.analyze.report.figures import restitution_figure
from impactlab.analyze.report.questions import restitution
from impactlab.analyze.report.standards import DROP_TESTS, drop_tests
from impactlab.physics import restitution_on_curve
from impactlab.show import number

ITF, ITTF = DROP_TESTS
XS, ES = (0.5, 1.0, 2.0, 4.0, 6.0, 8.0, 10.0), (0.86, 0.85, 0.83, 0.80, 0.77, 0.74, 0.71)
TENNIS, PING, HEAVY = (0.057, 0.033), (0.0027, 0.020), (1.0, 0.1)


def test_a_drop_test_is_e_between_the_square_roots_of_the_rebound_over_the_drop():
    assert ITF.band == pytest.approx((math.sqrt(134.62 / 254), math.sqrt(147.32 / 254)))
    assert ITF.band == pytest.approx((0.7280, 0.7616), abs=1e-4)
    assert ITTF.band == pytest.approx((math.sqrt(240 / 305), math.sqrt(265 / 305)))
    assert ITF.fits(*TENNIS) and not ITF.fits(*HEAVY) and not ITF.fits(0.057, None)
    assert ITTF.fits(*PING) and not ITTF.fits(*TENNIS)


def _bounce(run: str, drop: float, e: float, *, bounce: int = 1, complete: bool = True) -> dict:
    return {
        "run_id": run,
        "bounce": bounce,
        "complete": complete,
        "apex_before_m": drop,
        "v_in_mps": -math.sqrt(2 * 9.81 * drop),
        "e_velocity": e,
    }


def test_each_run_of_a_rules_ball_and_height_passes_or_fails_by_its_measured_e():
    bounces = pl.DataFrame(
        [
            _bounce("pass", 2.5401, 0.75),
            _bounce("fail", 2.54, 0.78),
            _bounce("low", 2.54, 0.70),
            _bounce("edge", 2.54 * 1.009, ITF.band[0]),  # 0.9 % off the height, e on the bound
            _bounce("higher", 2.60, 0.75),  # 2.4 % off the height: not the test
            _bounce("heavy", 2.54, 0.75),  # not a tennis ball
            _bounce("later", 2.54, 0.75, bounce=2),  # a second fall is not a drop
            _bounce("open", 2.54, 0.75, complete=False),
            _bounce("ping", 0.305, 0.91),
            _bounce("ping_low", 0.305, 0.85),
        ]
    )
    balls = {r: TENNIS for r in ("pass", "fail", "low", "edge", "higher", "later", "open")}
    balls |= {"heavy": HEAVY, "ping": PING, "ping_low": PING}
    found = drop_tests(bounces, balls)
    verdicts = dict(zip(found["run_id"], found["passed"], strict=True))
    assert verdicts == {
        "pass": True,
        "fail": False,
        "low": False,
        "edge": True,
        "ping": True,
        "ping_low": False,
    }
    row = found.filter(pl.col("run_id") == "pass").row(0, named=True)
    assert row["test"] == "ITF tennis ball" and row["speed_mps"] == pytest.approx(7.0594, abs=1e-3)
    assert drop_tests(bounces.clear(), balls).is_empty()


def _tables(bounces: pl.DataFrame, briefs: dict[str, RunBrief]) -> Tables:
    return Tables(pl.DataFrame(), bounces, pl.DataFrame(), pl.DataFrame(), {}, {}, briefs)


def _brief(run: str, experiment: str, *, curve: bool, ball=TENNIS) -> RunBrief:
    return RunBrief(
        run_id=run,
        experiment=experiment,
        label=f"{experiment}: {run}",
        grounded=True,
        targets=() if curve else (0.8,),
        masses=(ball[0],),
        bodies="ball",
        contact="",
        gravity_mps2=9.81,
        curves=((XS, ES),) if curve else (),
        radii=(ball[1],),
    )


def _real_ball(offsets: dict[float, float]) -> pl.DataFrame:
    """Bounces of one drop per first impact speed (m/s), each e its target + its offset."""
    rows = []
    for i, (v, off) in enumerate(offsets.items()):
        target = float(restitution_on_curve(v, XS, ES))
        rows.append(
            {
                **_bounce(f"r{i}", v * v / (2 * 9.81), target + off),
                "run": f"real_ball: r{i}",
                "body": "ball",
                "surface": "plane",
                "impact_t_s": 0.5,
                "target_e": target,
                "e_apex": None,
            }
        )
    return pl.DataFrame(rows)


def _said(t: Tables) -> str:
    """Step 2's evidence sentences, joined."""
    (bullets,) = [b for b in restitution(t).evidence if isinstance(b, Bullets)]
    return " ".join(str(span) for item in bullets.items for span in item)


def test_step_2_says_how_e_falls_against_its_target_and_judges_the_drop_test():
    itf = math.sqrt(2 * 9.81 * 2.54)
    bounces = _real_ball({1.0: 0.001, 3.0: -0.002, itf: 0.003, 9.0: -0.002})
    briefs = {r: _brief(r, "real_ball", curve=True) for r in bounces["run_id"]}
    said = _said(_tables(bounces, briefs))
    # one run's bounces at two speeds: not constant, as its target asks
    second = bounces.slice(3, 1).with_columns(
        run_id=pl.lit("r0"), bounce=pl.lit(2, pl.Int64), run=pl.lit("real_ball: r0")
    )
    two = pl.concat([bounces.head(1), second])
    lead = restitution(_tables(two, briefs)).finding
    spread = number(abs(two["e_velocity"][1] - two["e_velocity"][0]), 2)
    assert lead.startswith(
        f"No, e is not constant across bounces, as its target e(v) asks (real_ball: spread "
        f"up to {spread})"
    ), lead
    # beside a flat run, the flat one answers the question and the curve's is the exception
    flat = bounces.head(1).with_columns(run_id=pl.lit("f0"), run=pl.lit("drop: f0"))
    flat = pl.concat([flat, flat.with_columns(bounce=pl.lit(2, pl.Int64))])
    both = {**briefs, "f0": _brief("f0", "drop", curve=False)}
    lead = restitution(_tables(pl.concat([two, flat]), both)).finding
    assert lead.startswith("Yes, e is constant across bounces (spread at most 0, below 0.02)")
    assert f", except as a target e(v) asks (real_ball: spread up to {spread})" in lead
    assert "real_ball: the contact's target e falls by 0.12 over these speeds" in said
    assert "the measured e falls by 0.13, from 0.851 at 1.00 m/s to 0.723 at 9.00 m/s" in said
    assert "its 4 bounces are within 0.0030 of the target at its speed" in said
    assert "is the ITF tennis ball drop test (2.54 m, impact at 7.06 m/s)" in said
    target = float(restitution_on_curve(itf, XS, ES)) + 0.003
    assert f"measured e = {target:.3f}, the rule asks 0.728 to 0.762" in said
    assert "so it passes" in said

    off = _real_ball({1.0: 0.0, 9.0: 0.13})  # a flat e against a falling target
    briefs = {r: _brief(r, "real_ball", curve=True) for r in off["run_id"]}
    said = _said(_tables(off, briefs))
    assert "the measured e stays within 0.0050 of one value" in said
    assert "up to 0.13 off the target at its speed, more than 0.01" in said


def test_the_figure_draws_the_curve_beside_a_flat_target_and_the_pass_band(tmp_path):
    bounces = _real_ball({1.0: 0.0, 3.0: 0.0, 7.06: 0.0, 9.0: 0.0}).with_columns(
        pl.lit(True).alias("complete")
    )
    flat = bounces.with_columns(
        pl.col("run_id") + "f", pl.lit(0.8).alias("e_velocity"), pl.lit(None).alias("e_apex")
    )
    runs = {r: "real_ball" for r in bounces["run_id"]} | {r: "flat" for r in flat["run_id"]}
    path = restitution_figure(
        pl.concat([bounces, flat]),
        pl.DataFrame(),
        runs,
        path=tmp_path / "restitution-vs-speed.png",
        targets={"real_ball": [(XS, ES)], "flat": [0.8]},
        tests=[("ITF tennis ball", 7.06, *ITF.band)],
    )
    assert path.stat().st_size > 10_000
