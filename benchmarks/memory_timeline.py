"""Where an analysis' memory goes: its resident memory over time, with the place in
impactlab's code the main thread is at (`docs/performance.md`, "Scale").

    python benchmarks/memory_timeline.py LOGS OUT [local|processes]

Samples this process's RSS every 50 ms (workers not included) and prints one line per
change of place: seconds, MB, the innermost impactlab frames. Reading frames does not load
source files, so the sampling adds no memory of its own to speak of.
"""

from __future__ import annotations

import shutil
import sys
import threading
import time
from pathlib import Path
from types import FrameType

import psutil


def place(frame: FrameType | None, depth: int = 2) -> str:
    """The innermost `depth` impactlab frames of a stack: module:function:line."""
    found: list[str] = []
    while frame is not None and len(found) < depth:
        code = frame.f_code
        if "impactlab" in code.co_filename:
            found.append(f"{Path(code.co_filename).stem}:{code.co_name}:{frame.f_lineno}")
        frame = frame.f_back
    return " > ".join(reversed(found)) or "-"


def main(argv: list[str]) -> int:
    """Analyze LOGS into OUT (tables, summary and report, no figures), printing the timeline."""
    logs, out = argv[0], Path(argv[1])
    executor_name = argv[2] if len(argv) > 2 else "local"
    me, main_id = psutil.Process(), threading.main_thread().ident
    samples: list[tuple[float, float, str]] = []
    running = True

    def sample() -> None:
        start = time.perf_counter()
        while running:
            where = place(sys._current_frames().get(main_id or 0))
            samples.append((time.perf_counter() - start, me.memory_info().rss / 1e6, where))
            time.sleep(0.05)

    threading.Thread(target=sample, daemon=True).start()
    from impactlab.analyze.job import run_analysis
    from impactlab.executors.choose import make_executor

    shutil.rmtree(out, ignore_errors=True)
    executor = make_executor(executor_name)
    try:
        run_analysis([logs], out, figures=False, executor=executor)
    finally:
        executor.close()
    running = False
    last = None
    for t, mb, where in samples:
        if where != last:
            print(f"{t:8.2f} s {mb:8.1f} MB  {where}")
            last = where
    t, mb, where = max(samples, key=lambda s: s[1])
    print(f"peak {mb:.1f} MB at {t:.2f} s  {where}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
