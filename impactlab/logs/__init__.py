"""The log format, the one contract between the stages: one MCAP file per run.

Owns: topics, schema names and metadata keys (`format`), the fixed-layout protobuf codec
(`codec`, `messages`), writing (`chunks`, `writer`, `scene`;
`geoms`: the geom table and meshes that draw the model), reading (`reader` walks the
records, `load` decodes them into polars frames, damaged logs included), whether a log is
complete (`status`), `info` and `diff`.

May import: mcap, protobuf and the generated bindings (`impactlab.proto`), numpy, polars.
Must not import: MuJoCo or any stage (record, analyze, replay, calibrate): the stages
depend on the log format, never the other way round.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from impactlab.packages import lazy_exports

if TYPE_CHECKING:
    from impactlab.logs.diff import LogDiff as LogDiff
    from impactlab.logs.diff import Tolerance as Tolerance
    from impactlab.logs.diff import diff_logs as diff_logs
    from impactlab.logs.inputs import find_logs as find_logs
    from impactlab.logs.load import RunLog as RunLog
    from impactlab.logs.load import load_log as load_log

if not TYPE_CHECKING:  # a type checker sees the imports above
    __getattr__ = lazy_exports(
        __name__,
        {
            "RunLog": "impactlab.logs.load",
            "find_logs": "impactlab.logs.load",
            "load_log": "impactlab.logs.load",
            "diff_logs": "impactlab.logs.diff",
            "LogDiff": "impactlab.logs.diff",
            "Tolerance": "impactlab.logs.diff",
        },
    )
