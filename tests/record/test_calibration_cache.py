"""A sweep's runs are planned again when they are read (the plan is lazy); their pairs are
calibrated once per process for the same arguments all the same."""

from __future__ import annotations

from paths import EXPERIMENTS

from impactlab.record import contact_pairs as contact_pairs
from impactlab.record.planner import plan


def test_reading_a_lazy_plan_again_calibrates_nothing_again():
    contact_pairs._calibrated.cache_clear()
    runs = plan([EXPERIMENTS / "drop_restitution.toml"])
    first = [run.pairs for run in runs]
    again = [run.pairs for run in runs]
    calls = contact_pairs._calibrated.cache_info().misses  # contact_params really called
    assert len(runs) == 3 and calls == 3  # one calibration per sweep point
    assert again == first and all(len(pairs) == 1 for pairs in first)
