"""Scale: large sweeps of short runs recorded and analyzed end to end (`bench.py --scale`).

Each stage (record, then analyze: tables, summary.json and the report, no figures) runs in
a fresh interpreter (`cases.py`); its peak memory is that of the whole process tree (the
stage's process and every child: record's forked workers, the analysis' worker processes),
the sum of their resident memory sampled with psutil every 20 ms. Time per run is the
stage's own time (planning included, the interpreter's start not) over the number of runs.
The goals (issue 28): at 20,000 runs, time per run within 1.2x and peak memory within 1.3x
of those at 2,000; larger sweeps (100,000) are measured against 2,000 the same way.

The machine's speed drifts by a quarter within the hour, so each larger sweep is
bracketed: the smallest is measured first and again right after each larger one, and a
larger sweep's ratios are taken against the mean of the two measurements around it.
"""

from __future__ import annotations

import contextlib
import json
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import cases
import psutil
from results import Results

SAMPLE_S = 0.02
GOAL_TIME, GOAL_MEMORY = 1.2, 1.3


def tree_rss(process: psutil.Process) -> int:
    """Resident bytes of the process and all its descendants (those alive now)."""
    total = 0
    for p in [process, *process.children(recursive=True)]:
        with contextlib.suppress(psutil.Error):  # ended between the listing and the reading
            total += p.memory_info().rss
    return total


def run_sampled(argv: list[str]) -> tuple[dict, float]:
    """Run a command, sampling its process tree's memory; its JSON result and peak MB."""
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, text=True)
    watched = psutil.Process(proc.pid)
    peak = 0
    while proc.poll() is None:
        with contextlib.suppress(psutil.Error):
            peak = max(peak, tree_rss(watched))
        time.sleep(SAMPLE_S)
    out = proc.stdout.read() if proc.stdout else ""
    if proc.returncode != 0:
        raise SystemExit(f"{argv[2:]} failed with exit code {proc.returncode}")
    return json.loads(out.strip().splitlines()[-1]), peak / 1e6


def measuring_order(sizes: list[int]) -> list[int]:
    """The sizes in the order they are measured: the smallest first and again right after
    each larger one (`[2000, 20000, 2000, 100000, 2000]`)."""
    small = min(sizes)
    return [small, *(n for large in sorted(set(sizes) - {small}) for n in (large, small))]


def scale(folder: Path, specs: dict[int, Path], executors: list[str]) -> Iterator[dict]:
    """Record each size's spec, analyze it on each executor; one row per (size, executor),
    as it is measured, in `measuring_order` (`slot`: the place in it; `again`: the
    smallest measured again). `specs`: per number of runs, its sweep spec."""
    for k, n in enumerate(measuring_order(list(specs))):
        spec, again = specs[n], k > 0 and n == min(specs)
        logs = folder / f"scale_logs_{n}"
        rec, rec_mb = run_sampled([sys.executable, cases.__file__, "record", str(spec), str(logs)])
        assert rec["runs"] == n, rec
        for executor in executors:
            out = folder / f"scale_results_{n}_{executor}"
            ana, ana_mb = run_sampled(
                [sys.executable, cases.__file__, "tables", str(logs), str(out), executor]
            )
            row = {
                "runs": n,
                "slot": k,
                "again": again,
                "executor": executor,
                "record_ms": rec["seconds"] * 1e3 / n,
                "record_cpu_ms": rec["cpu_seconds"] * 1e3 / n,
                "record_mb": rec_mb,
                "analyze_ms": ana["seconds"] * 1e3 / n,
                "analyze_cpu_ms": ana["cpu_seconds"] * 1e3 / n,
                "analyze_mb": ana_mb,
            }
            _print_row(row)
            yield row
        shutil.rmtree(logs, ignore_errors=True)  # 100,000 logs are 4 GB


def _print_row(r: dict) -> None:
    print(
        f"  {r['runs']:>6}{'*' if r['again'] else ' '}{r['executor']:>9} {r['record_ms']:>10.2f} {r['record_cpu_ms']:>8.2f} "
        f"{r['record_mb']:>10.0f} {r['analyze_ms']:>11.2f} {r['analyze_cpu_ms']:>9.2f} "
        f"{r['analyze_mb']:>11.0f}",
        flush=True,
    )


def main(
    folder: Path,
    specs: dict[int, Path],
    executors: list[str],
    results: Results,
    write: Callable[[Results], object],
) -> None:
    """Measure every size on every executor; print the rows and ratios. `results` holds
    the rows measured so far and is written (`write`) after each: a long run stopped
    before its end leaves the figures it measured."""
    print(
        "scale: sweeps of short runs (0.05 s, 101 steps) recorded, then analyzed (tables, "
        "summary.json, report; no figures), each stage in a fresh interpreter; peak MB of "
        "the whole process tree (sampled every 20 ms)"
    )
    print(
        f"  {'runs':>6} {'executor':>9} {'record ms':>10} {'CPU ms':>8} {'record MB':>10} "
        f"{'analyze ms':>11} {'CPU ms':>9} {'analyze MB':>11}"
    )
    rows: list[dict] = []
    planned = len(measuring_order(list(specs))) * len(executors)
    for row in scale(folder, specs, executors):
        rows.append(row)
        _fill(results, rows, executors, planned)
        write(results)
    print("  (*: the smallest sweep measured again, right after the larger one above it)")
    for text in _ratios(rows, executors):
        print(text)


def _ratios(rows: list[dict], executors: list[str]) -> Iterator[str]:
    """Each larger size against the smallest, per stage: the lines to print."""
    small = min(r["runs"] for r in rows)
    for large in sorted({r["runs"] for r in rows} - {small}):
        yield (
            f"  ratios {large:,} runs / {small:,} runs (goals: time <= {GOAL_TIME}, memory <= "
            f"{GOAL_MEMORY}):"
        )
        for stage, where, t, c, m in _compare(rows, executors, small, large):
            verdict = "met" if t <= GOAL_TIME and m <= GOAL_MEMORY else "not met"
            yield (
                f"    {stage}{where}: time per run {t:.2f}x (CPU {c:.2f}x), peak memory "
                f"{m:.2f}x: {verdict}"
            )


def _compare(
    rows: list[dict], executors: list[str], small: int, large: int
) -> Iterator[tuple[str, str, float, float, float]]:
    """(stage, executor note, time ratio, CPU time ratio, memory ratio) of `large` runs
    against `small`."""
    for executor in executors:
        b = [r for r in rows if r["runs"] == large and r["executor"] == executor]
        if not b:
            continue
        around = {b[0]["slot"] - 1, b[0]["slot"] + 1}  # the smallest, before and after
        a = [
            r
            for r in rows
            if r["runs"] == small and r["executor"] == executor and r["slot"] in around
        ]
        if not a:
            continue
        for stage in ("record", "analyze"):
            if stage == "record" and executor != executors[0]:
                continue  # recorded once per size

            def mean(key: str, a: list[dict] = a) -> float:  # of the smallest's, around it
                return sum(r[key] for r in a) / len(a)

            t = b[0][f"{stage}_ms"] / mean(f"{stage}_ms")
            c = b[0][f"{stage}_cpu_ms"] / mean(f"{stage}_cpu_ms")
            m = b[0][f"{stage}_mb"] / mean(f"{stage}_mb")
            yield stage, "" if stage == "record" else f" ({executor})", t, c, m


def _fill(results: Results, rows: list[dict], executors: list[str], planned: int) -> None:
    """`results` with the rows measured so far and the ratios they allow."""
    results.rows.clear()
    results.tables.clear()
    results.notes.clear()
    results.table(
        [
            "runs",
            "analyze executor",
            "record ms/run",
            "record CPU ms/run",
            "record peak MB",
            "analyze ms/run",
            "analyze CPU ms/run",
            "analyze peak MB",
        ],
        [
            [
                f"{r['runs']:,}" + (" (again)" if r["again"] else ""),
                r["executor"],
                f"{r['record_ms']:.2f}",
                f"{r['record_cpu_ms']:.2f}",
                f"{r['record_mb']:.0f}",
                f"{r['analyze_ms']:.2f}",
                f"{r['analyze_cpu_ms']:.2f}",
                f"{r['analyze_mb']:.0f}",
            ]
            for r in rows
        ],
    )
    small = min(r["runs"] for r in rows)
    for large in sorted({r["runs"] for r in rows} - {small}):
        for stage, where, t, c, m in _compare(rows, executors, small, large):
            results.add(
                "ratio",
                f"{stage}{where}, {large:,} runs against {small:,}",
                f"time per run {t:.2f}x (CPU {c:.2f}x), peak memory {m:.2f}x",
                f"time <= {GOAL_TIME}x, memory <= {GOAL_MEMORY}x",
                t <= GOAL_TIME and m <= GOAL_MEMORY,
            )
    if len(rows) < planned:
        results.note(f"**Incomplete**: {len(rows)} of the {planned} rows measured so far.")
    results.note(
        "Runs of 0.05 s (101 steps), drop sweep. Each stage in a fresh interpreter; peak "
        "memory of the whole process tree (the stage's process and its workers, resident "
        "memory summed, sampled every 20 ms); time per run: the stage's time, planning "
        "included, over the runs; CPU: the user and system seconds of the stage's process and "
        "its workers over the same span (what the stage costs whatever else the machine "
        "runs; the verdict is on the time). The smallest sweep is measured first and again "
        "right after each larger one; a larger sweep's ratios are against the "
        "mean of the smallest's two measurements around it (the machine's speed drifts by a "
        "quarter within the hour). The analysis is given the logs' folder, as "
        "`impactlab analyze FOLDER` is. Record shares the runs among forked workers, one per core; "
        "the analysis (tables only) runs in one process (`local`) or in its own process and "
        "one worker process per other CPU (`processes`)."
    )
