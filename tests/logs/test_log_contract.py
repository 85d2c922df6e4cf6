"""The keys of format 2 (`impactlab.logs.metadata`): what the analysis reads instead of the spec.

The recorder writes them from what it planned; a log of format 1 (the golden logs as they
were before format 2: `tests/golden/format1/`) lacks them: it is read, not analyzed.
"""

from __future__ import annotations

import pytest
from paths import GOLDEN

from impactlab.errors import LogError
from impactlab.logs import format as logformat
from impactlab.logs.load import load_log
from impactlab.logs.metadata import GeomContact
from impactlab.physics import INTEGRATORS, half_step_s

DEFAULT_CONTACT = GeomContact((0.02, 1.0), (0.9, 0.95, 0.001, 0.5, 2.0))  # the spec's


def _pair(name: str):
    """(format-1 log, format-2 log) of one golden run."""
    return load_log(GOLDEN / "format1" / f"{name}.mcap"), load_log(GOLDEN / "logs" / f"{name}.mcap")


def test_the_half_step_is_half_a_timestep_for_the_semi_implicit_integrators_only():
    assert [half_step_s(i, 1e-3) for i in INTEGRATORS] == [5e-4, 0.0, 5e-4, 5e-4]
    with pytest.raises(ValueError, match="unknown integrator 'Verlet'"):
        half_step_s("Verlet", 1e-3)


def test_a_format1_log_reads_without_the_keys_of_format_2_which_its_recording_has():
    """A format-1 log is read (info, diff, replay) but not analyzed (`test_bounce_rules`):
    the keys of format 2 it lacks read as unknown, and lacking them is no problem."""
    old, new = _pair("collision")
    assert (old.meta["log_format_version"], new.meta["log_format_version"]) == ("1", "3")
    assert not set(logformat.RUN_KEYS_FORMAT_2) & set(old.meta)  # written before format 2
    assert set(logformat.RUN_KEYS_FORMAT_2) <= set(new.meta)
    assert not old.partial and not new.partial, (old.problems, new.problems)
    assert old.unanalyzable() is None  # its metadata is sound: its format is what is refused
    assert (old.separation_m, old.geom_contact, old.contact_targets) == (None, None, ())
    with pytest.raises(LogError, match="damaged metadata: half_step_s: missing"):
        _ = old.half_step_s
    # golden collision.toml: separation = 0.1, dt = 1e-4 s, Euler
    assert new.separation_m == 0.1
    assert new.half_step_s == pytest.approx(0.5e-4, rel=1e-12)
    assert new.geom_contact == DEFAULT_CONTACT and new.contact_targets == ()


def test_a_calibrated_drop_records_its_target_and_speed_range():
    new = load_log(GOLDEN / "logs" / "drop_restitution.mcap")
    (n,) = new.contact_targets
    assert (n.pair, n.restitution) == ("plane/ball", 0.9)
    assert n.speed_range_mps is not None and 0 < n.speed_range_mps[0] <= n.speed_range_mps[1]
    # golden drop_restitution.toml: dt = 1e-5 s, Euler, no separation
    assert new.separation_m is None
    assert new.half_step_s == pytest.approx(0.5e-5, rel=1e-12)
    assert new.geom_contact == DEFAULT_CONTACT


def test_the_recorded_targets_are_the_planned_calibration():
    from impactlab.record import plan

    (run,) = plan([GOLDEN / "specs" / "drop_restitution.toml"])
    (pair,) = run.pairs
    (target,) = load_log(GOLDEN / "logs" / "drop_restitution.mcap").contact_targets
    assert (target.geom1, target.geom2) == (pair.geom1, pair.geom2)
    assert target.restitution == pair.params.restitution
    assert target.speed_range_mps == pytest.approx(pair.params.speed_range_mps, rel=1e-12)


def test_a_user_model_says_its_geoms_contact_and_no_separation():
    run = load_log(GOLDEN / "logs" / "box_edge.mcap")  # box_edge.xml: <geom solref, solimp>
    assert run.geom_contact is not None and run.geom_contact.solref == (-100000.0, -63.245553)
    assert run.separation_m is None and run.contact_targets == ()
    assert run.half_step_s == pytest.approx(run.timestep_s / 2, rel=1e-12)
