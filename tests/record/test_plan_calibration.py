"""A spec run's pairs are calibrated when it is planned, never when its model is built: the
model and the log's `contact_targets` take them from the planned run, also on an executor's
worker."""

from __future__ import annotations

import pickle

import mujoco
import pytest
from paths import GOLDEN

from impactlab.record import model as model_module
from impactlab.record import planner as planner
from impactlab.record.log_rows import shared_geom_contact
from impactlab.record.recorder import portable

SPEC = GOLDEN / "specs" / "drop_restitution.toml"


def test_a_spec_run_is_calibrated_once_and_its_model_uses_that_calibration(monkeypatch):
    calls = []
    calibrate = planner.calibrated_pairs

    def counted(run):
        calls.append(run)
        return calibrate(run)

    def refuse(run):
        raise AssertionError("calibrated again when the model is built")

    monkeypatch.setattr(planner, "calibrated_pairs", counted)
    monkeypatch.setattr(model_module, "calibrated_pairs", refuse)
    (run,) = planner.plan([SPEC])  # plan() builds the first model of a sweep to check it
    planned = len(calls)  # a lazy plan may plan a run again when it is read, never more
    assert planned >= 1
    shipped = pickle.loads(pickle.dumps(portable(run)))  # as a Ray task receives it
    for inst in (run.build(), shipped.build()):
        (pair,) = run.pairs
        assert inst.model.npair == 1
        assert tuple(inst.model.pair_solref[0]) == pytest.approx(pair.params.solref, rel=1e-12)
    assert len(calls) == planned  # building models and shipping the run: no calibration
    (target,) = run.info.contact_targets
    assert (target.restitution, target.speed_range_mps) == (
        pair.params.restitution,
        pair.params.speed_range_mps,
    )


def _model(box_solref: str) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(
        '<mujoco><default><geom solref="0.03 1.5"/></default><worldbody>'
        '<geom type="plane" size="1 1 0.1"/><body><freejoint/>'
        f'<geom type="box" size="0.1 0.1 0.1" {box_solref}/></body></worldbody></mujoco>'
    )


def test_the_geoms_contact_is_recorded_only_when_every_geom_shares_it():
    shared = shared_geom_contact(_model(""))
    assert shared is not None and shared.solref == (0.03, 1.5)
    assert shared.solimp == (0.9, 0.95, 0.001, 0.5, 2.0)  # MuJoCo's default
    assert shared_geom_contact(_model('solref="0.02 1"')) is None
