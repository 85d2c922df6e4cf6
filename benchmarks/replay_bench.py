"""Time the replay of a long log: record a ~100,000-step drop, then load it and convert it.

Run: python benchmarks/replay_bench.py [--steps 100000] [--keep DIR]
Prints the seconds spent loading the log (impactlab.logs.load) and converting it to .rrd.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from impactlab.logs.load import load_log
from impactlab.record import plan, record_runs
from impactlab.replay.recordings import write_recording

SPEC = """
name = "bench"
description = "replay benchmark: a ball bouncing on the plane for {steps} steps"

[options]
timestep = 0.0001
integrator = "Euler"
gravity = [0.0, 0.0, -9.81]

[contact]
condim = 3
solref = [-20000.0, -5.0]

[bodies.ball]
radius = 0.1
mass = 1.0
pos = [0.0, 0.0, 1.0]
vel = [0.5, 0.0, 0.0]
angvel = [0.0, 3.0, 0.0]

[stop]
max_time = {max_time}
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000, help="steps to record (100000)")
    parser.add_argument("--keep", type=Path, help="folder to keep the log and the .rrd in")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        spec = folder / "bench.toml"
        spec.write_text(SPEC.format(steps=args.steps, max_time=(args.steps - 1) * 1e-4))
        start = time.perf_counter()
        (result,) = record_runs(plan([spec]), folder)
        recorded = time.perf_counter() - start

        start = time.perf_counter()
        run = load_log(result.path)
        loaded = time.perf_counter() - start

        start = time.perf_counter()
        out = write_recording([run], folder / "bench.rrd")
        converted = time.perf_counter() - start

        steps = next(iter(run.bodies.values())).height
        print(f"steps logged: {steps}, contact rows: {run.contacts.height}")
        print(f"record:  {recorded:6.2f} s ({result.path.stat().st_size / 1e6:.1f} MB .mcap)")
        print(f"load:    {loaded:6.2f} s")
        print(f"convert: {converted:6.2f} s ({out.stat().st_size / 1e6:.1f} MB .rrd)")


if __name__ == "__main__":
    main()
