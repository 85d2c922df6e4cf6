"""The batched analysis against the plain per-run reference (`analyze/measure/reference.py`):
the same energies and the same impact and release speeds, for logs written every step and
every 5th step, with the semi-implicit integrator and with RK4."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest
from paths import GOLDEN
from specs import DIRECT, drop, toml

from impactlab.analyze.measure import reference
from impactlab.analyze.measure.analysis import analyze_run
from impactlab.cli import main
from impactlab.logs.load import RunLog, load_log


def recorded(tmp_path: Path, integrator: str, every: int) -> RunLog:
    spec = tmp_path / f"{integrator}-{every}.toml"
    spec.write_text(
        toml(
            drop(
                "oracle_drop",
                timestep=0.0005,
                integrator=integrator,
                contact=DIRECT,
                max_time=2.0,
                bounces=3,
                every=every,
            )
        )
    )
    out = tmp_path / spec.stem
    assert main(["record", str(spec), "-o", str(out)]) == 0
    (path,) = out.glob("*.mcap")
    return load_log(path)


@pytest.fixture(scope="module", params=[("Euler", 1), ("Euler", 5), ("RK4", 5), ("golden", 1)])
def run(request, tmp_path_factory) -> RunLog:
    integrator, every = request.param
    if integrator == "golden":
        return load_log(GOLDEN / "logs" / "drop_bounces.mcap")
    return recorded(tmp_path_factory.mktemp("oracle"), integrator, every)


def test_energy_equals_the_reference(run: RunLog):
    energy = analyze_run(run).energy
    for body in run.bodies:
        mine = energy.filter(pl.col("body") == body).sort("t_ns")
        plain = reference.body_energy(run, body)
        for column in ("ke_trans_J", "ke_rot_J"):
            np.testing.assert_allclose(
                mine[column].to_numpy(), plain[column], rtol=1e-12, atol=1e-12
            )
        pe = mine["pe_J"].to_numpy()
        np.testing.assert_allclose(pe - pe[0], plain["pe_J"], rtol=1e-12, atol=1e-9)


def test_impact_and_release_speeds_equal_the_reference(run: RunLog):
    bounces = analyze_run(run).bounces.filter(pl.col("complete")).sort("impact_t_s")
    assert bounces.height >= 2
    t = run.bodies["ball"]["t_s"].to_numpy()
    contacts = reference.ground_contacts(run, "ball")
    for row in bounces.iter_rows(named=True):
        (mine,) = [c for c in contacts if t[c.first - 1] <= row["impact_t_s"] <= t[c.first]]
        v_in, v_out = reference.ball_speeds(run, mine)
        assert row["v_in_mps"] == pytest.approx(v_in, rel=1e-9)
        assert row["v_out_mps"] == pytest.approx(v_out, rel=1e-9)
        assert row["e_velocity"] == pytest.approx(-v_out / v_in, rel=1e-9)
