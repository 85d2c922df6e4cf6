"""Memory of the end of an analysis, step by step: the runs table with its parameters, the
studies, the labels, the headline and each answer, from an analysis folder's written tables
(`docs/performance.md`, "Scale").

    python benchmarks/report_memory.py OUT [COPIES]

OUT is a folder `impactlab analyze` wrote; with COPIES > 1 its tables are repeated that
many times with new run ids (the tables of 20,000 runs copied five times stand for 100,000).
Prints, per step, this process's RSS and what it added, and what Python's own allocations
kept and peaked at (tracemalloc). Run it with `_RJEM_MALLOC_CONF=dirty_decay_ms:0,
muzzy_decay_ms:0` so that polars' allocator gives freed pages back and RSS shows what is live.
"""

from __future__ import annotations

import sys
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import polars as pl
import psutil

from impactlab.analyze.report import answers, handout, headline
from impactlab.analyze.tables.labels import run_labels, with_labels
from impactlab.analyze.tables.studies import studies, study_parameters, with_parameters

TABLES = ("runs", "bounces", "phases", "collisions")


def load(folder: Path, copies: int) -> dict[str, pl.DataFrame]:
    """The tables, each repeated `copies` times with the copy's number added to its run ids."""
    out = {}
    for name in TABLES:
        frame = pl.read_parquet(folder / f"{name}.parquet").rechunk()
        if copies > 1 and frame.height:
            frame = pl.concat(
                [frame.with_columns(pl.col("run_id") + f"-{k}") for k in range(copies)]
            ).rechunk()
        out[name] = frame
    return out


def main(argv: list[str]) -> int:
    """Load, then run each step, printing its memory."""
    folder, copies = Path(argv[0]), int(argv[1]) if len(argv) > 1 else 1
    me = psutil.Process()
    t = load(folder, copies)
    print(f"{t['runs'].height:,} runs loaded: {me.memory_info().rss / 1e6:.1f} MB")
    tracemalloc.start()

    def step(name: str, make: Callable[[], Any]) -> Any:
        tracemalloc.reset_peak()
        before, rss = tracemalloc.get_traced_memory()[0], me.memory_info().rss / 1e6
        out = make()
        now, peak = tracemalloc.get_traced_memory()
        after = me.memory_info().rss / 1e6
        print(
            f"  {name:26s} RSS {after:7.1f} MB ({after - rss:+6.1f})  Python kept "
            f"{(now - before) / 1e6:+6.1f} MB, peak {(peak - before) / 1e6:+6.1f} MB",
            flush=True,
        )
        return out

    runs = step("runs with parameters", lambda: with_parameters(t["runs"]))
    swept = step("studies", lambda: studies(runs))
    params = {name: study_parameters(runs, name) for name in swept}
    labels = step("run labels", lambda: run_labels(runs))
    named = step("labels on four tables", lambda: {n: with_labels(t[n], labels) for n in TABLES})
    named_runs, bounces, collisions = named["runs"], named["bounces"], named["collisions"]
    step(
        "headline",
        lambda: list(
            headline.headline(
                out_dir=folder,
                runs=named_runs,
                bounces=bounces,
                collisions=collisions,
                studies=swept,
                params=params,
                figures={},
            )
        ),
    )
    step("as written", lambda: list(handout.as_written_section(named_runs, collisions)))
    for name, answer in (
        ("energy answer", lambda: answers.energy_answer(named_runs)),
        ("e across bounces", lambda: answers.constancy_answer(named_runs, bounces)),
        ("collision answer", lambda: answers.collision_answer(collisions, named_runs)),
    ):
        step(name, lambda answer=answer: sum(1 for _ in answer()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
