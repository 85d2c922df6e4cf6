"""Calibrate: the calibration experiment recorded and analyzed, every impact against its target.

Owns: recording the shipped calibration specs (`experiments/calibration/`) and analyzing them
(`job`), the table of every impact of a calibrated pair against its target or the designer's
prediction, and its section of the report (`table`).

May import: the public faces of `impactlab.record` and `impactlab.analyze`, `impactlab.contact`,
`impactlab.examples`. Must not import: the internals of other stages, `impactlab.replay`.
"""

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
