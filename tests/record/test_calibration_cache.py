"""A sweep's runs are planned again when they are read (the plan is lazy); their pairs are
calibrated once per process for the same arguments all the same."""

from __future__ import annotations

from paths import EXPERIMENTS

from impactlab.record import contact_pairs as contact_pairs
from impactlab.record.planner import plan


def test_reading_a_lazy_plan_again_calibrates_nothing_again(monkeypatch):
    calls = []
    calibrate = contact_pairs.contact_params

    def counted(*args, **kwargs):
        calls.append(args)
        return calibrate(*args, **kwargs)

    monkeypatch.setattr(contact_pairs, "contact_params", counted)
    contact_pairs._calibrated.cache_clear()
    runs = plan([EXPERIMENTS / "drop_restitution.toml"])
    first = [run.pairs for run in runs]
    again = [run.pairs for run in runs]
    assert len(runs) == 3 and len(calls) == 3  # one calibration per sweep point
    assert again == first and all(len(pairs) == 1 for pairs in first)
