"""Calibrate: how well does a target restitution come out of recorded logs?

Owns: the calibration grids (`grid`), recording and measuring them (`run`), the job that
writes tables, figures and calibration.md (`job`, `report`, `plots`).

May import: the public faces of `impactlab.record` and `impactlab.analyze`, `impactlab.contact`,
`impactlab.physics`. Must not import: the internals of other stages, `impactlab.replay`.
"""

from __future__ import annotations

from impactlab.packages import lazy_exports

__getattr__ = lazy_exports(
    __name__,
    {
        "CalibrationResult": "impactlab.calibrate.run",
        "choose_grid": "impactlab.calibrate.job",
        "run_calibration": "impactlab.calibrate.job",
    },
)
