"""The log format, the one contract between the stages: one MCAP file per run (docs/log-format.md).

May import: mcap, protobuf and the generated bindings, numpy, polars, pydantic. Must not
import MuJoCo or any stage: the stages depend on the log format, never the other way round.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from impactlab.packages import lazy_exports

if TYPE_CHECKING:
    from impactlab.logs.inputs import find_logs as find_logs
    from impactlab.logs.load import RunLog as RunLog
    from impactlab.logs.load import load_log as load_log

if not TYPE_CHECKING:  # a type checker sees the imports above
    __getattr__ = lazy_exports(
        __name__,
        {
            "RunLog": "impactlab.logs.load",
            "find_logs": "impactlab.logs.inputs",
            "load_log": "impactlab.logs.load",
        },
    )
