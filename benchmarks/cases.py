"""The benchmark's cases: each measures one thing and returns its figures as a dict.

`bench.py` and `scale.py` call them here, or in a fresh interpreter (`python cases.py KIND
ARGS...`, which prints the case's JSON result with its peak memory as the last line) when
a case's memory or start must be its own.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
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
    from handout_loop import step_all

    from impactlab.record.model import mjcf_from_spec
    from impactlab.record.sweep import load_runs

    runs = load_runs(spec)
    models = [mujoco.MjModel.from_xml_string(mjcf_from_spec(r)) for r in runs]
    steps = round(runs[0].stop.max_time / runs[0].options.timestep) + 1
    start = time.perf_counter()
    step_all(models, steps)
    return time.perf_counter() - start, steps * len(models)


def bare_loop_argv(spec: Path, folder: Path) -> list[str]:
    """The handout's loop as a whole `python` process over the sweep's models (written as
    MJCF files into `folder`), the same steps as `impactlab record` simulates."""
    from impactlab.record.model import mjcf_from_spec
    from impactlab.record.sweep import load_runs

    runs = load_runs(spec)
    folder.mkdir(parents=True, exist_ok=True)
    for i, run in enumerate(runs):
        (folder / f"run_{i:05d}.xml").write_text(mjcf_from_spec(run))
    steps = round(runs[0].stop.max_time / runs[0].options.timestep) + 1
    return [
        sys.executable,
        str(Path(__file__).with_name("handout_loop.py")),
        str(folder),
        str(steps),
    ]


def record_case(spec: Path, out: Path, threads: int, *, with_plan: bool = False) -> dict:
    """Record a spec; seconds (planning included `with_plan`), steps and runs."""
    from impactlab.record import plan, record_runs

    start, cpu = time.perf_counter(), _cpu_seconds()
    runs = plan([spec])
    if not with_plan:
        start, cpu = time.perf_counter(), _cpu_seconds()
    results = record_runs(runs, out, threads=threads, overwrite=True)
    seconds = time.perf_counter() - start
    steps = sum(r.steps for r in results)
    return {
        "seconds": seconds,
        "cpu_seconds": _cpu_seconds() - cpu,
        "steps": steps,
        "runs": len(results),
    }


def large_model_case(xml: Path, duration: float, out: Path, turns: int) -> dict:
    """A large MJCF model recorded with impactlab's API against a bare `mj_step` loop of
    the same steps (the model as MuJoCo loads it, nothing read), in one process, in turns
    (loop, plan, record, loop, plan, record, ..., loop). Each recording is paired with the
    loops just before and after it: its ratios (wall and CPU) are to their mean. The
    machine's speed drifts by tens of percent from minute to minute (the same loop took
    1.27 to 2.20 s), so the best of each side alone would pair unrelated moments. Returns
    every turn's figures (lists); planning (compile, instrument, attachments) is apart."""
    import mujoco

    from impactlab.record import plan, record_runs
    from impactlab.record.work import run_steps

    def loop() -> tuple[float, float]:
        model = mujoco.MjModel.from_xml_path(str(xml))
        data = mujoco.MjData(model)
        start, cpu = time.perf_counter(), _cpu_seconds()
        for _ in range(steps):
            mujoco.mj_step(model, data)
        return time.perf_counter() - start, _cpu_seconds() - cpu

    steps = run_steps(duration, float(mujoco.MjModel.from_xml_path(str(xml)).opt.timestep))
    keys = ("loop_s", "loop_cpu", "plan_s", "plan_cpu", "record_s", "record_cpu", "wall", "cpu")
    found: dict[str, list[float]] = {key: [] for key in keys}
    before = loop()
    for _ in range(turns):
        start, cpu = time.perf_counter(), _cpu_seconds()
        runs = plan([xml], duration=duration)
        found["plan_s"].append(time.perf_counter() - start)
        found["plan_cpu"].append(_cpu_seconds() - cpu)
        start, cpu = time.perf_counter(), _cpu_seconds()
        (result,) = record_runs(runs, out, threads=1, overwrite=True)
        record = time.perf_counter() - start, _cpu_seconds() - cpu
        if result.failed or result.steps != steps:
            raise RuntimeError(f"{xml.name}: {result.steps} steps recorded, not {steps}")
        after = loop()
        pair = [(b + a) / 2 for b, a in zip(before, after, strict=True)]
        found["loop_s"].append(pair[0])
        found["loop_cpu"].append(pair[1])
        found["record_s"].append(record[0])
        found["record_cpu"].append(record[1])
        found["wall"].append(record[0] / pair[0])
        found["cpu"].append(record[1] / pair[1])
        before = after
    return found | {"steps": steps}


def _cpu_seconds() -> float:
    """CPU seconds (user and system) of this process and of its children waited for (the
    workers, once a stage has closed them): a stage's cost, whatever else the machine runs."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


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
) -> dict:  # logs: log files, or folders of them (as `impactlab analyze` is given)
    """The whole analysis of the logs (tables and report; figures when asked), on the
    executor `impactlab analyze` uses by default (worker processes) or another."""
    from impactlab.analyze.job import run_analysis
    from impactlab.executors.choose import make_executor

    start, cpu = time.perf_counter(), _cpu_seconds()
    with_executor = make_executor(executor)
    try:
        run_analysis(logs, out, figures=figures, executor=with_executor)
    finally:
        with_executor.close()
    return {"seconds": time.perf_counter() - start, "cpu_seconds": _cpu_seconds() - cpu}


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
    (best,) = commands_in_turns([argv], repeat)
    return best


def commands_in_turns(argvs: list[list[str]], repeat: int = 3) -> list[float]:
    """Best wall time of each command, as `command_seconds`, the commands run in turns
    (a, b, a, b, ...) after a warm-up run of each: a ratio of two of them is moved less by
    the machine's speed drifting between their measurements."""
    import os

    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    for argv in argvs:
        subprocess.run(argv, capture_output=True, check=True, env=env)
    best = [float("inf")] * len(argvs)
    for _ in range(repeat):
        for i, argv in enumerate(argvs):
            start = time.perf_counter()
            subprocess.run(argv, capture_output=True, check=True, env=env)
            best[i] = min(best[i], time.perf_counter() - start)
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
    """Run one case in a fresh interpreter; its JSON result plus peak RSS."""
    out = subprocess.run(
        [sys.executable, __file__, *args], capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def run_case(case: list[str]) -> int:
    """Run the case `case` names (kind, then its arguments); print its JSON result."""
    kind = case[0]
    if kind == "record":  # planning included: a stage of a sweep, as a user waits for it
        result = record_case(Path(case[1]), Path(case[2]), threads=2, with_plan=True)
    elif kind == "record1":  # one core: this process pinned to one CPU
        import os

        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
        result = record_case(Path(case[1]), Path(case[2]), threads=1)
    elif kind == "analyze":
        result = analyze_case(sorted(Path(case[1]).glob("*.mcap")), Path(case[2]))
    elif kind == "tables":  # tables, summary.json and report of a folder of logs, given
        # as the folder (`impactlab analyze FOLDER`): its logs are listed by the analysis
        result = analyze_case([Path(case[1])], Path(case[2]), figures=False, executor=case[3])
    else:
        raise SystemExit(f"unknown case {kind}")
    children_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # workers
    result["peak_mb"] = max(_peak_rss_mb(), children_mb)
    print(json.dumps(result))
    return 0


def _peak_rss_mb() -> float:
    """This process's peak resident memory (VmHWM: unlike ru_maxrss, not inherited over exec)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


if __name__ == "__main__":
    raise SystemExit(run_case(sys.argv[1:]))
