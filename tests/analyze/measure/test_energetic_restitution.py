"""The energetic coefficient of restitution, from the work the recorder accumulates over
every simulated step of a contact (`impactlab.record.contact_work`).

A tilted cube on MuJoCo's direct-form dashpot (k = 1e5, zeta = 0.1: e = 0.7441 for a point
mass) lands on corners and edges: its contact point can leave faster than it came (the
velocity ratio exceeds 1), while the contact returns no more energy than it takes (the
energetic coefficient stays below 1). Neither changes with the logging stride.
"""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest
from specs import mjcf_drop

from impactlab.analyze.measure.analysis import analyze_run
from impactlab.cli import main
from impactlab.logs.load import load_log

E_DASHPOT = 0.7441  # Schwager-Poeschel, zeta = 0.1

CUBE = mjcf_drop("cube", "box", "0.05 0.05 0.05", 0.5, euler="20 35 10", condim=3)


def bounces(tmp_path: Path, every: int) -> pl.DataFrame:
    model = tmp_path / "cube.xml"
    model.write_text(CUBE)
    out = tmp_path / f"every{every}"
    args = ["record", str(model), "-o", str(out), "--duration", "1.2"]
    assert main([*args, "--set", f"logging.every={every}"]) == 0
    (path,) = out.glob("*.mcap")
    return analyze_run(load_log(path)).bounces.filter(pl.col("impact_t_s").is_not_null())


@pytest.fixture(scope="module")
def cube(tmp_path_factory) -> tuple[pl.DataFrame, pl.DataFrame]:
    root = tmp_path_factory.mktemp("cube")
    return bounces(root, 1), bounces(root, 5)


@pytest.mark.slow
def test_a_turning_cube_leaves_faster_than_it_came_but_returns_less_energy(cube):
    rows, _ = cube
    fast = rows.filter(pl.col("e_velocity") > 1)
    assert fast.height >= 1  # the velocity ratio of a corner impact
    for e, e_c, note in fast.select("e_velocity", "e_energy", "note").iter_rows():
        # the note quotes the contact's own work, e_energy, and the budget's other works
        assert note.startswith(f"e_velocity {e:.3g} is outside [0, 1]"), note
        assert f"(e_energy {e_c:.3g})" in note and "the model's other forces:" in note
    done = rows.filter(pl.col("e_energy").is_not_null())
    assert done.height >= 5
    assert done["e_energy"].max() <= 1.0
    # the dashpot's dissipation, whatever the corner: near the point-mass value
    assert done["e_energy"].min() > E_DASHPOT - 0.08 and done["e_energy"].max() < E_DASHPOT + 0.05
    assert set(done["e_basis"]) == {"energy"}  # the cube turns: the velocity ratio is not e


def test_the_energetic_coefficient_does_not_depend_on_the_logging_stride(cube):
    every1, every5 = cube
    joined = every1.join(every5, on=["body", "surface", "bounce"], suffix="_5")
    assert joined.height == every1.height
    done = joined.filter(pl.col("e_energy").is_not_null())
    assert done.height >= 5
    for a, b in zip(done["e_energy"], done["e_energy_5"], strict=True):
        assert a == pytest.approx(b, rel=1e-9)
