"""Calibrate: the calibration experiment recorded and analyzed, every impact against its target."""

from __future__ import annotations

from impactlab.packages import lazy_exports

__getattr__ = lazy_exports(
    __name__,
    {
        "CalibrationResult": "impactlab.calibrate.job",
        "report_blocks": "impactlab.calibrate.job",
        "run_calibration": "impactlab.calibrate.job",
    },
)
