"""Runs per second of one sweep on the local executor and on a local Ray cluster, side by side.

Run: python benchmarks/ray_bench.py [--runs 32] [--cpus 2] [--max-time 2.0]
Needs Ray (pip install 'impactlab[ray]'). Records the same drop sweep (`--runs` heights)
into fresh folders: twice with the local executor (batched multi-threaded rollouts in
this process), then twice on a Ray instance started here with `--cpus` CPUs ("cold": the
first sweep, whose workers import impactlab; "warm": the same workers again). Ray's start
time is printed apart. The logs of all four are checked to be byte-identical.
"""

from __future__ import annotations

import argparse
import logging
import os
import tempfile
import time
from pathlib import Path

from cases import write_spec  # the same drop sweep as the main benchmark

from impactlab.record import plan, record_runs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=32, help="sweep points (32)")
    parser.add_argument("--cpus", type=int, default=os.cpu_count(), help="Ray CPUs (all)")
    parser.add_argument("--max-time", type=float, default=2.0, help="simulated s per run (2)")
    args = parser.parse_args()

    import ray

    from impactlab.executors.ray import RayExecutor

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        spec = write_spec(folder, args.runs, args.max_time)
        runs = plan([spec])
        rows = []

        for label in ("local", "local2"):  # the second one is warm, like the Ray workers
            start = time.perf_counter()
            record_runs(runs, folder / label)
            rows.append(
                (
                    f"local executor ({'first' if label == 'local' else 'again'})",
                    time.perf_counter() - start,
                )
            )

        start = time.perf_counter()
        ray.init(
            num_cpus=args.cpus, num_gpus=0, include_dashboard=False, logging_level=logging.WARNING
        )
        ray_start = time.perf_counter() - start
        executor = RayExecutor()
        try:
            for label in ("cold", "warm"):
                start = time.perf_counter()
                sweep = record_runs(runs, folder / label, executor=executor)
                rows.append(
                    (f"ray, {executor.slots} CPUs ({label} workers)", time.perf_counter() - start)
                )
                assert len(sweep.recorded) == len(runs), sweep.failed
        finally:
            ray.shutdown()

        names = sorted(p.name for p in (folder / "local").glob("*.mcap"))
        same = all(
            (folder / "local" / n).read_bytes()
            == (folder / "cold" / n).read_bytes()
            == (folder / "warm" / n).read_bytes()
            == (folder / "local2" / n).read_bytes()
            for n in names
        )
        print(f"{len(runs)} drop runs, {args.max_time:g} s simulated each, {os.cpu_count()} cores")
        print(f"{'executor':<36} {'wall s':>8} {'runs/s':>8}")
        for label, seconds in rows:
            print(f"{label:<36} {seconds:8.2f} {len(runs) / seconds:8.2f}")
        print(f"ray start (not in the figures): {ray_start:.2f} s")
        print(f"logs byte-identical across executors: {same}")


if __name__ == "__main__":
    main()
