"""Benchmark: recording, decoding, analysis and replay, each against its baseline, in one run.

Usage: python benchmarks/bench.py [--quick]   (or `just bench`)
       python benchmarks/bench.py --scale [--runs 2000 20000] [--executors local processes]

Every figure is measured here, on this machine, in this run:
- record: a 64-run drop sweep with every step logged on every channel, against the same
  steps simulated by the handout's Python loop (mj_step, copy qpos/qvel, nothing logged);
- decode: logs into polars frames (messages per second, one process), against the official
  mcap reader iterating over the same files;
- analyze: the whole analysis of the sweep, against the time it took to record it;
- replay: a 100,000-step log converted to .rrd;
- scale: 1x, 4x, 16x runs and steps, one thread against two, peak memory of each case
  (each case runs in a fresh subprocess so its peak RSS is its own);
- --scale: large sweeps of short runs recorded and analyzed end to end, time per run and
  peak memory of the whole process tree (`benchmarks/scale.py`).
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SPEC = """
name = "bench_drop"
description = "benchmark drop sweep: handout contact, every step logged"
[options]
timestep = 0.0005
[contact]
condim = 1
solref = [0.02, 1.0]
solimp = [0.9, 0.95, 0.001]
[bodies.ball]
radius = 0.1
mass = 1.0
pos = [0.0, 0.0, 1.0]
[stop]
max_time = {max_time}
[sweep]
"ball.pos" = [{heights}]
"""


def write_spec(folder: Path, runs: int, max_time: float) -> Path:
    """A drop sweep of `runs` heights from 1 m, every step logged, fixed duration."""
    heights = ", ".join(f"[0.0, 0.0, {1.0 + 0.05 * i:.2f}]" for i in range(runs))
    path = folder / f"bench_{runs}_{max_time:g}.toml"
    path.write_text(SPEC.format(max_time=max_time, heights=heights))
    return path


def handout_loop(spec: Path) -> tuple[float, int]:
    """Seconds and steps for the handout's loop over the sweep's models (nothing logged)."""
    import mujoco
    import numpy as np

    from impactlab.record.model import mjcf_from_spec
    from impactlab.record.sweep import load_runs

    runs = load_runs(spec)
    models = [mujoco.MjModel.from_xml_string(mjcf_from_spec(r)) for r in runs]
    steps = round(runs[0].stop.max_time / runs[0].options.timestep) + 1
    start = time.perf_counter()
    for model in models:
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, 0)
        qpos, qvel = [], []
        for _ in range(steps):
            mujoco.mj_step(model, data)
            qpos.append(data.qpos.copy())
            qvel.append(data.qvel.copy())
        np.asarray(qpos)
    return time.perf_counter() - start, steps * len(models)


def record_case(spec: Path, out: Path, threads: int) -> dict:
    """Record a spec; seconds, steps and messages."""
    from impactlab.record import plan, record_runs

    runs = plan([spec])
    start = time.perf_counter()
    results = record_runs(runs, out, threads=threads, overwrite=True)
    seconds = time.perf_counter() - start
    steps = sum(r.steps for r in results)
    return {"seconds": seconds, "steps": steps, "runs": len(results)}


def decode_case(logs: list[Path]) -> dict:
    """Decode logs into frames; messages decoded per second."""
    from impactlab.logs.load import load_log

    start = time.perf_counter()
    runs = [load_log(path) for path in logs]
    seconds = time.perf_counter() - start
    messages = 0  # counted after the timing: a count is not decoding
    for run in runs:
        messages += sum(f.height for f in run.bodies.values()) + run.energy.height
        messages += run.contacts["t_ns"].n_unique() if run.contacts.height else 0
        messages += run.events.height
    return {"seconds": seconds, "messages": messages}


def official_case(logs: list[Path]) -> dict:
    """The official mcap reader iterating over every message of the same files."""
    from mcap.reader import make_reader

    start = time.perf_counter()
    messages = 0
    for path in logs:
        with open(path, "rb") as stream:
            for _ in make_reader(stream).iter_messages():
                messages += 1
    return {"seconds": time.perf_counter() - start, "messages": messages}


def analyze_case(
    logs: list[Path], out: Path, figures: bool = True, executor: str = "processes"
) -> dict:
    """The whole analysis of the logs (tables and report; figures when asked), on the
    executor `impactlab analyze` uses by default (worker processes) or another."""
    from impactlab.analyze.job import run_analysis
    from impactlab.executors.choose import make_executor

    start = time.perf_counter()
    with_executor = make_executor(executor)
    try:
        run_analysis(logs, out, figures=figures, executor=with_executor)
    finally:
        with_executor.close()
    return {"seconds": time.perf_counter() - start}


def zstd_case(logs: list[Path]) -> dict:
    """The limit of decoding: zstd decompression of the same logs' chunks (bytes out per s)."""
    import zstandard
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    chunks = []
    for path in logs:
        with open(path, "rb") as stream:
            for record in StreamReader(stream, skip_magic=False, emit_chunks=True).records:
                if isinstance(record, Chunk) and record.compression == "zstd":
                    chunks.append((record.data, record.uncompressed_size))
    decompress = zstandard.ZstdDecompressor().decompress
    start = time.perf_counter()
    out_bytes = sum(len(decompress(data, max_output_size=size)) for data, size in chunks)
    return {"seconds": time.perf_counter() - start, "bytes": out_bytes, "chunks": len(chunks)}


def command_seconds(argv: list[str], repeat: int = 3) -> float:
    """Best wall time of a command in a fresh interpreter (what a user waits for).

    As on an installed package: bytecode is written and used (one warm-up run first), even
    where PYTHONDONTWRITEBYTECODE is set (which alone adds about 0.1 s of compiling).
    """
    import os

    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    subprocess.run(argv, capture_output=True, check=True, env=env)
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run(argv, capture_output=True, check=True, env=env)
        best = min(best, time.perf_counter() - start)
    return best


def replay_case(folder: Path) -> dict:
    """A 100,000-step log converted to .rrd."""
    from impactlab.record import plan, record_runs
    from impactlab.replay.recordings import replay_logs

    spec = folder / "replay.toml"
    spec.write_text(
        SPEC.format(max_time=9.9999, heights="[0.0, 0.0, 2.0]").replace(
            "timestep = 0.0005", "timestep = 0.0001"
        )
    )
    (result,) = record_runs(plan([spec]), folder / "replay_logs")
    start = time.perf_counter()
    replay_logs([result.path], out=folder / "replay.rrd", analysis_dir=None)
    return {"seconds": time.perf_counter() - start, "steps": result.logged}


def subprocess_case(args: list[str]) -> dict:
    """Run one case of this script in a fresh interpreter; its JSON result plus peak RSS."""
    out = subprocess.run(
        [sys.executable, __file__, "--case", *args], capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="16 runs instead of 64, no scale")
    parser.add_argument("--case", nargs="+", help=argparse.SUPPRESS)
    parser.add_argument("--scale", action="store_true", help="only the large-sweep scale case")
    parser.add_argument("--runs", type=int, nargs="+", default=[2000, 20000])
    parser.add_argument("--executors", nargs="+", default=["local", "processes"])
    args = parser.parse_args()
    if args.case:
        return _run_case(args.case)
    if args.scale:
        import scale

        print(f"machine: {_machine()}")
        with tempfile.TemporaryDirectory(prefix="impactlab-scale-") as tmp:
            specs = {n: write_spec(Path(tmp), n, 0.05) for n in sorted(set(args.runs))}
            scale.main(Path(tmp), __file__, specs, args.executors)
        return 0
    runs = 16 if args.quick else 64
    with tempfile.TemporaryDirectory(prefix="impactlab-bench-") as tmp:
        folder = Path(tmp)
        spec = write_spec(folder, runs, 3.0)
        print(f"machine: {_machine()}")
        base_s, base_steps = handout_loop(spec)
        rec2 = record_case(spec, folder / "logs", threads=2)
        rec1 = subprocess_case(["record1", str(spec), str(folder / "logs1")])
        us = 1e6 / rec2["steps"]
        print(f"\nrecord: {runs}-run drop sweep, {rec2['steps']} steps, every step logged")
        print(
            f"  handout loop, nothing logged : {base_s:7.2f} s  ({base_s * 1e6 / base_steps:.2f} us/step)"
        )
        print(
            f"  impactlab record, 2 cores    : {rec2['seconds']:7.2f} s  ({rec2['seconds'] * us:.2f} us/step; "
            "a forked worker per core)"
        )
        print(
            f"  impactlab record, one core   : {rec1['seconds']:7.2f} s  (pinned to one CPU, one process)"
        )
        print(f"  ratio record / handout loop  : {rec2['seconds'] / base_s:.2f}  (goal <= 1.0)")
        print(
            f"  two cores over one (pinned)  : {rec1['seconds'] / rec2['seconds']:.2f}x  (goal >= 1.8)"
        )
        logs = sorted((folder / "logs").glob("*.mcap"))
        dec = decode_case(logs)
        off = official_case(logs)
        ours_rate = dec["messages"] / dec["seconds"]
        official_rate = off["messages"] / off["seconds"]
        print(f"\ndecode: {len(logs)} logs into polars frames")
        print(
            f"  impactlab load_log           : {dec['seconds']:7.2f} s  {ours_rate / 1e6:.2f} M msg/s ({dec['messages']} msgs; /tf skipped)"
        )
        print(
            f"  official reader iter_messages: {off['seconds']:7.2f} s  {official_rate / 1e6:.3f} M msg/s ({off['messages']} msgs, no decoding)"
        )
        print(
            f"  ratio (per message)          : {ours_rate / official_rate:.1f}x  (goal >= 30, and >= 4 M msg/s)"
        )
        zst = zstd_case(logs)
        zstd_mb_s = zst["bytes"] / zst["seconds"] / 1e6
        print(
            f"  limit: zstd on the same chunks: {zst['seconds']:7.2f} s  {zstd_mb_s:.0f} MB/s "
            f"({zst['chunks']} chunks, {zst['bytes'] / 1e6:.0f} MB out); decode runs at "
            f"{zst['seconds'] / dec['seconds']:.2f} of it"
        )
        ana = analyze_case(logs, folder / "results")
        tab = analyze_case(logs, folder / "tables", figures=False)
        one = analyze_case(logs, folder / "tables1", figures=False, executor="local")
        print(f"\nanalyze: the sweep; recording it took {rec2['seconds']:.2f} s")
        print(
            f"  with figures and report      : {ana['seconds']:7.2f} s  ratio "
            f"{ana['seconds'] / rec2['seconds']:.2f} of the recording (goal <= 0.5)"
        )
        print(
            f"  tables only (--no-figures)   : {tab['seconds']:7.2f} s  ratio "
            f"{tab['seconds'] / rec2['seconds']:.2f} of the recording (goal <= 0.2)"
        )
        print(
            f"  tables only, one process     : {one['seconds']:7.2f} s  ratio "
            f"{one['seconds'] / rec2['seconds']:.2f} (--executor local; the rows above use "
            f"one worker process per CPU, the default)"
        )
        _startup(folder)
        rep = replay_case(folder)
        print(f"\nreplay: {rep['steps']}-step log to .rrd: {rep['seconds']:.2f} s (goal < 2 s)")
        if not args.quick:
            _scale(folder)
    return 0


def _startup(folder: Path) -> None:
    exe = [sys.executable, "-m", "impactlab"]
    root = Path(__file__).resolve().parent.parent
    help_s = command_seconds([*exe, "--help"])
    mujoco_s = command_seconds([sys.executable, "-c", "import mujoco"])
    python_s = command_seconds([sys.executable, "-c", "pass"])
    drop = [*exe, "record", str(root / "experiments" / "drop.toml"), "-o", str(folder / "drop")]
    record_s = command_seconds([*drop, "--overwrite"])
    print("\nstart-up: best of 3 after a warm-up, fresh interpreter each, bytecode cached")
    print(f"  python -c pass               : {python_s:7.2f} s")
    print(f"  impactlab --help             : {help_s:7.2f} s  (goal <= 0.3)")
    print(f"  python -c 'import mujoco'    : {mujoco_s:7.2f} s")
    print(f"  impactlab record drop.toml   : {record_s:7.2f} s in all  (goal <= 0.5)")


def _scale(folder: Path) -> None:
    print("\nscale: record (every core) in fresh processes; peak RSS per case (workers included)")
    print(
        f"  {'runs':>5} {'max_time s':>10} {'steps':>9} {'seconds':>8} {'us/step':>8} {'peak MB':>8}"
    )
    for runs, max_time in [(4, 0.75), (4, 3.0), (4, 12.0), (16, 0.75), (64, 0.75)]:
        spec = write_spec(folder, runs, max_time)
        r = subprocess_case(["record", str(spec), str(folder / f"scale_{runs}_{max_time}")])
        print(
            f"  {runs:>5} {max_time:>10g} {r['steps']:>9} {r['seconds']:>8.2f} "
            f"{r['seconds'] * 1e6 / r['steps']:>8.2f} {r['peak_mb']:>8.0f}"
        )
    print(
        "  sweeps of short runs (0.05 s, 101 steps) recorded and analyzed (tables only) end to end:"
    )
    print(
        f"  {'runs':>5} {'executor':>8} {'record s':>8} {'ms/run':>7} {'analyze s':>9} "
        f"{'ms/run':>7} {'peak MB':>8}"
    )
    for runs, executor in [(250, "local"), (2000, "local"), (2000, "processes"), (2000, "ray")]:
        spec = write_spec(folder, runs, 0.05)
        r = subprocess_case(
            ["sweep", str(spec), str(folder / f"sweep_{runs}_{executor}"), executor]
        )
        print(
            f"  {runs:>5} {executor:>8} {r['record_s']:>8.2f} {r['record_s'] * 1e3 / runs:>7.2f} "
            f"{r['analyze_s']:>9.2f} {r['analyze_s'] * 1e3 / runs:>7.2f} {r['peak_mb']:>8.0f}"
        )
    print("  analysis (decode + analyze) of the 4-run cases:")
    for max_time in (0.75, 3.0, 12.0):
        logs = folder / f"scale_4_{max_time}"
        r = subprocess_case(["analyze", str(logs), str(folder / f"scale_results_{max_time}")])
        print(f"    max_time {max_time:>5g} s: {r['seconds']:6.2f} s, peak {r['peak_mb']:.0f} MB")


def _run_case(case: list[str]) -> int:
    kind = case[0]
    if kind == "record":
        result = record_case(Path(case[1]), Path(case[2]), threads=2)
    elif kind == "record1":  # one core: this process pinned to one CPU
        import os

        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
        result = record_case(Path(case[1]), Path(case[2]), threads=1)
    elif kind == "sweep":  # record then analyze (tables only), on the local or a Ray executor
        result = _sweep_case(Path(case[1]), Path(case[2]), case[3])
    elif kind == "analyze":
        result = analyze_case(sorted(Path(case[1]).glob("*.mcap")), Path(case[2]))
    elif kind == "tables":  # tables, summary.json and report of a folder of logs
        logs = sorted(Path(case[1]).glob("*.mcap"))
        result = analyze_case(logs, Path(case[2]), figures=False, executor=case[3])
    else:
        raise SystemExit(f"unknown case {kind}")
    children_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # workers
    result["peak_mb"] = max(_peak_rss_mb(), children_mb)
    print(json.dumps(result))
    return 0


def _sweep_case(spec: Path, out: Path, executor_name: str) -> dict:
    """A sweep recorded and analyzed end to end; seconds of each stage."""
    from impactlab.analyze.job import run_analysis
    from impactlab.record import plan, record_runs

    executor = None
    if executor_name == "processes":
        from impactlab.executors.processes import ProcessExecutor

        executor = ProcessExecutor()
    if executor_name == "ray":
        import logging

        import ray

        from impactlab.executors.ray import RayExecutor

        ray.init(include_dashboard=False, logging_level=logging.WARNING)
        executor = RayExecutor()
    runs = plan([spec])
    start = time.perf_counter()
    recorded = record_runs(runs, out / "logs", executor=executor, overwrite=True)
    record_s = time.perf_counter() - start
    start = time.perf_counter()
    run_analysis(recorded.paths, out / "results", figures=False, executor=executor)
    analyze_s = time.perf_counter() - start
    if executor_name == "ray":
        ray.shutdown()
    if executor is not None:
        executor.close()
    return {"record_s": record_s, "analyze_s": analyze_s, "runs": len(runs)}


def _peak_rss_mb() -> float:
    """This process's peak resident memory (VmHWM: unlike ru_maxrss, not inherited over exec)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _machine() -> str:
    import os
    import platform

    import mujoco

    return (
        f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"MuJoCo {mujoco.__version__}"
    )


if __name__ == "__main__":
    raise SystemExit(main())
