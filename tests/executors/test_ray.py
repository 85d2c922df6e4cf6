"""The executors: a small sweep on a local Ray cluster equals the local executor's.

One Ray instance (2 CPUs, 200 MB object store, no dashboard) serves the whole module; it
is started by `ray.init` and stopped by `ray.shutdown`, which end only its own processes.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from pathlib import Path

import polars as pl
import pytest
from polars.testing import assert_frame_equal
from specs import drop, toml

from impactlab.analyze.job import run_analysis
from impactlab.cli import main
from impactlab.executors.base import LocalExecutor
from impactlab.executors.choose import RAY_INSTALL_HINT
from impactlab.record import plan, record_runs
from impactlab.record.recorder import task_ranges

pytestmark = [pytest.mark.slow, pytest.mark.extras]  # a local Ray cluster (the ray extra)

# Four short drops; solref [2, 1] is so soft that the ball sinks through the floor (unstable).
SPEC = toml(
    drop(
        "raysweep",
        description="drop sweep for the Ray tests",
        z=0.5,
        max_time=0.6,
        sweep={"contact.solref": [[0.02, 1.0], [0.02, 0.5], [2.0, 1.0], [0.01, 1.0]]},
    )
)
# its run id ends with the spec's hash, which changes with the spec schema's defaults
UNSTABLE = next(r.info.run_id for r in plan(tomllib.loads(SPEC)) if "solref=2_1" in r.info.run_id)
TABLES = ("runs", "bounces", "collisions", "energy", "phases")


@pytest.fixture(scope="module")
def ray_executor(tmp_path_factory):
    """A RayExecutor on a local 2-CPU Ray instance started for this module."""
    import ray

    from impactlab.executors.ray import RayExecutor

    os.environ.setdefault("RAY_DISABLE_IMPORT_WARNING", "1")
    ray.init(
        num_cpus=2,
        num_gpus=0,
        object_store_memory=200 * 1024**2,
        include_dashboard=False,
        logging_level="WARNING",
    )
    try:
        yield RayExecutor()
    finally:
        ray.shutdown()


@pytest.fixture(scope="module")
def spec_path(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("spec") / "raysweep.toml"
    path.write_text(SPEC)
    return path


@pytest.fixture(scope="module")
def local_logs(spec_path, tmp_path_factory) -> dict[str, bytes]:
    out = tmp_path_factory.mktemp("local")
    results = record_runs(plan([spec_path]), out)
    return {r.path.name: r.path.read_bytes() for r in results}


@pytest.fixture(scope="module")
def ray_sweep(ray_executor, spec_path, tmp_path_factory, collect_lines):
    out = tmp_path_factory.mktemp("ray")
    lines: list[str] = []
    sweep = record_runs(
        plan([spec_path]), out, executor=ray_executor, progress=collect_lines(lines)
    )
    return out, sweep, lines


def test_ray_logs_are_byte_identical_to_the_local_executor(local_logs, ray_sweep):
    out, sweep, _ = ray_sweep
    assert [r.status for r in sweep] == ["recorded"] * 4
    assert sorted(p.name for p in out.glob("*.mcap")) == sorted(local_logs)
    for name, data in local_logs.items():
        # byte for byte: both recorded on this machine in this session (local Ray workers)
        assert (out / name).read_bytes() == data, name
    assert not list(out.glob("*.partial"))


def test_unstable_point_is_reported_with_its_reason_and_the_others_complete(ray_sweep):
    _, sweep, lines = ray_sweep
    (bad,) = sweep.unstable
    assert bad.run_id == UNSTABLE
    assert bad.reason.startswith("penetration ") and "> 0.1 m" in bad.reason
    assert sum(r.outcome == "completed" for r in sweep) == 3
    assert sweep.exit_code == 1
    assert any(line.startswith(f"{UNSTABLE}.mcap: unstable (penetration") for line in lines)


def test_ray_analysis_equals_the_local_analysis(
    ray_executor, ray_sweep, tmp_path, monkeypatch, capsys
):
    logs, _, _ = ray_sweep
    monkeypatch.chdir(logs.parent)  # relative paths, as typed: the tables show them
    (tmp_path / "junk.mcap").write_bytes(b"not an mcap file")
    inputs = [logs.name, str(tmp_path / "junk.mcap")]
    here = run_analysis(inputs, tmp_path / "local")
    local_err = capsys.readouterr().err
    there = run_analysis(inputs, tmp_path / "ray", executor=ray_executor)
    assert capsys.readouterr().err == local_err
    assert here.runs.height == 4 and here.runs["file"][0].startswith(f"{logs.name}/")
    assert there.failed == here.failed and [p for p, _ in here.failed] == [
        str(tmp_path / "junk.mcap")
    ]
    for name in TABLES:
        assert_frame_equal(getattr(there, name), getattr(here, name))
    assert there.studies.keys() == here.studies.keys()
    for name, study in here.studies.items():
        assert_frame_equal(there.studies[name], study)
    for name in (*TABLES, "summary.json"):
        file = name if "." in name else f"{name}.parquet"
        if file.endswith(".parquet"):
            assert_frame_equal(
                pl.read_parquet(tmp_path / "ray" / file), pl.read_parquet(tmp_path / "local" / file)
            )
        else:
            assert (tmp_path / "ray" / file).read_text() == (tmp_path / "local" / file).read_text()
    # exact: the same logs analyzed on this machine in one session, here and by local workers
    assert (tmp_path / "ray/report.md").read_text() == (tmp_path / "local/report.md").read_text()
    assert [p.relative_to(tmp_path / "ray") for p in there.files] == [
        p.relative_to(tmp_path / "local") for p in here.files
    ]
    assert all(p.is_file() for p in there.files)


def test_rerun_reuses_every_complete_log_without_running_tasks(spec_path, ray_sweep, collect_lines):
    out, _, _ = ray_sweep

    class NoTasks(LocalExecutor):
        name = "ray"

        def map(self, fn, items):
            raise AssertionError("nothing should run")

    lines: list[str] = []
    sweep = record_runs(plan([spec_path]), out, executor=NoTasks(), progress=collect_lines(lines))
    assert [r.status for r in sweep] == ["reused"] * 4
    assert lines == [f"reused 4 complete log(s) in {out}/, running 0"]
    assert [r.run_id for r in sweep.unstable] == [UNSTABLE]  # its log says so: still exit 1
    assert sweep.exit_code == 1


def test_a_run_that_cannot_be_written_fails_alone(
    ray_executor, spec_path, tmp_path, local_logs, collect_lines
):
    runs = plan([spec_path])
    blocked = tmp_path / f"{runs[1].info.run_id}.mcap"
    blocked.mkdir()  # a folder where the log should go: os.replace fails for this run only
    errors: list[str] = []
    sweep = record_runs(
        runs, tmp_path, executor=ray_executor, progress=collect_lines(errors, "error")
    )
    (failed,) = sweep.failed
    assert failed.run_id == runs[1].info.run_id
    assert failed.reason.startswith("cannot write the log: IsADirectoryError")
    assert errors == [f"impactlab: error: {failed.run_id}: {failed.reason}"]
    assert [r.status for r in sweep] == ["recorded", "failed", "recorded", "recorded"]
    assert sweep.exit_code == 1
    for r in sweep.recorded:
        assert r.path.read_bytes() == local_logs[r.path.name]
    # resume after the fix: only the failed run is recorded
    blocked.rmdir()
    again = record_runs(runs, tmp_path, executor=ray_executor)
    assert [r.status for r in again] == ["reused", "recorded", "reused", "reused"]
    assert blocked.read_bytes() == local_logs[blocked.name]


def test_a_task_that_raises_fails_its_item_with_the_reason(ray_executor):
    def task(x: int) -> int:
        if x == 2:
            raise ValueError(f"bad item {x}")
        return x * x

    outcomes = sorted(ray_executor.map(task, [0, 1, 2, 3]), key=lambda o: o.index)
    assert [o.value for o in outcomes] == [0, 1, None, 9]
    assert [o.error for o in outcomes] == [None, None, "ValueError: bad item 2", None]
    local = list(LocalExecutor().map(task, [0, 1, 2, 3]))
    assert [(o.value, o.error) for o in local] == [(o.value, o.error) for o in outcomes]


def test_cli_on_a_running_cluster_by_address_then_resume(ray_executor, spec_path, tmp_path):
    import ray

    address = ray.get_runtime_context().gcs_address
    out = tmp_path / "logs"
    cli = "import sys; from impactlab.cli import main; sys.exit(main())"
    cmd = [sys.executable, "-c", cli, "record", str(spec_path), "-o", str(out)]
    cmd += ["--set", "contact.solref=[[0.02, 1.0], [0.01, 1.0]]"]
    cmd += ["--executor", "ray", "--address", address]
    first = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stderr
    assert first.stdout.splitlines()[-1] == f"2 run(s) written to {out}/"
    assert len(list(out.glob("*.mcap"))) == 2
    second = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert second.returncode == 0, second.stderr
    assert second.stdout.splitlines() == [
        f"reused 2 complete log(s) in {out}/, running 0",
        f"0 run(s) written to {out}/",
    ]


def test_task_ranges_give_every_slot_several_small_tasks():
    assert task_ranges(0, 4) == []
    assert [len(g) for g in task_ranges(5, 2)] == [1] * 5
    assert [len(g) for g in task_ranges(32, 2)] == [4] * 8
    assert [len(g) for g in task_ranges(1000, 2)] == [16] * 62 + [8]
    assert [x for g in task_ranges(37, 3) for x in g] == list(range(37))


@pytest.mark.parametrize("command", ["record", "analyze", "lab"])
def test_without_ray_asking_for_it_is_one_error_line(
    command, monkeypatch, tmp_path, spec_path, capsys
):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` raises ImportError
    monkeypatch.delitem(sys.modules, "impactlab.executors.ray", raising=False)
    target = {"record": str(spec_path), "analyze": str(tmp_path), "lab": "--no-replay"}[command]
    code = main([command, target, "-o", str(tmp_path / "out"), "--executor", "ray"])
    err = capsys.readouterr().err
    assert code == 2
    assert err == (
        f"impactlab: error: --executor ray needs Ray, which is not installed: {RAY_INSTALL_HINT}\n"
    )
    assert not (tmp_path / "out").exists()


def test_an_mjcf_model_records_the_same_on_ray(ray_executor, tmp_path):
    model = tmp_path / "box.xml"
    model.write_text(
        """<mujoco><worldbody><geom type="plane" size="1 1 0.1"/>
        <body pos="0 0 0.3"><freejoint/><geom type="box" size="0.05 0.05 0.05"/></body>
        </worldbody></mujoco>"""
    )
    runs = plan([model], duration=0.3)
    (local,) = record_runs(runs, tmp_path / "local")
    sweep = record_runs(runs, tmp_path / "ray", executor=ray_executor)
    (summary,) = sweep.recorded
    assert summary.outcome == "completed"
    assert summary.path.read_bytes() == local.path.read_bytes()  # same machine, same session
