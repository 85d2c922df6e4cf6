"""Replay: logs recorded here -> .rrd files, verified by the `rerun` CLI and read back chunk by chunk.

The recordings are read with Rerun's own reader (`rerun.chunk.RrdReader`), independent of the
code that wrote them; expected counts come from the logs' frames through a plain reference.
"""

from __future__ import annotations

import math
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import polars as pl
import pytest
import rerun as rr
from paths import EXPERIMENTS, GOLDEN
from specs import collision, drop, toml

from impactlab import cli
from impactlab.analyze.measure.analysis import analyze_run
from impactlab.logs.load import RunLog, load_log
from impactlab.record import plan, record_runs
from impactlab.replay import recordings
from impactlab.replay.convert import run_prefix
from impactlab.replay.recordings import replay_logs

RERUN = Path(sys.executable).parent / "rerun"

DROP = toml(
    drop(
        "replay_drop",
        vel=[0.3, 0.0, 0.0],
        angvel=[0.0, 5.0, 0.0],
        timestep=0.0005,
        gravity=[0.0, 0.0, -9.81],
        contact={"solref": [-20000.0, -5.0]},
        max_time=1.5,
    )
)

BALLS = {"names": ("ball1", "ball2"), "masses": (1.0, 2.0), "z": 0.5}
COLLISION = toml(collision("replay_collision", timestep=0.0005, separation=0.1, **BALLS))


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A bouncing drop on the plane and a head-on collision, recorded once for the module."""
    folder = tmp_path_factory.mktemp("logs")
    out = {}
    for name, text in (("drop", DROP), ("collision", COLLISION)):
        spec = folder / f"{name}.toml"
        spec.write_text(text)
        (result,) = record_runs(plan([spec]), folder / "mcap")
        out[name] = result.path
    return out


def _copy(log: Path, folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / log.name
    target.write_bytes(log.read_bytes())
    return target


def _verify(path: Path) -> None:
    done = subprocess.run([str(RERUN), "rrd", "verify", str(path)], capture_output=True)
    assert done.returncode == 0, done.stderr.decode()


def _read(path: Path) -> dict[str, list]:
    """Temporal chunks of the first recording in the file, as record batches per entity path."""
    chunks: dict[str, list] = defaultdict(list)
    for chunk in rr.chunk.RrdReader(path).stream():
        if not chunk.is_static:
            chunks[chunk.entity_path].append(chunk.to_record_batch())
    return chunks


def _times_ns(batches: list) -> np.ndarray:
    return np.concatenate([b.column("sim_time").cast("int64").to_numpy() for b in batches]).astype(
        np.int64
    )


def _texts(chunks: dict[str, list], path: str) -> list[str]:
    return [t[0] for b in chunks.get(path, []) for t in b.column("TextLog:text").to_pylist()]


def _details(chunks: dict[str, list], path: str) -> list[str]:
    """The details of each event, logged beside its text (shown in the selection panel)."""
    return [t[0] for b in chunks.get(path, []) for t in b.column("details").to_pylist()]


def _kind(text: str) -> str:
    """An event text's kind, after the run's label among several runs ("drop: impact ...")."""
    return next(word for word in text.split() if word in ("impact", "release"))


def _reference_intervals(run: RunLog) -> tuple[int, int]:
    """Impacts and releases: the recorder's episodes, and those that ended (plain loop)."""
    impacts = releases = 0
    for ep in run.impacts.iter_rows(named=True):
        impacts += 1
        releases += not ep["open"] and ep["v_in_mps"] < 0
    return impacts, releases


def _check_run(chunks: dict[str, list], run: RunLog) -> None:
    prefix = run_prefix(run.run_id)
    t = next(iter(run.bodies.values()))["t_ns"].to_numpy()
    times = np.concatenate([_times_ns(b) for p, b in chunks.items() if p.startswith(prefix)])
    assert times.min() == t[0] and times.max() == t[-1]
    for body in run.bodies:
        batches = chunks[f"{prefix}/world/bodies/{body}"]
        np.testing.assert_array_equal(_times_ns(batches), t)
        assert f"{prefix}/world/trails/{body}" in chunks
        assert f"{prefix}/world/velocity/{body}" in chunks
    families = ["contact_force", "energy"] + (["height"] if run.surfaces else [])
    for family in families:
        assert any(p.startswith(f"{prefix}/series/{family}/") for p in chunks), family
    assert f"{prefix}/world/contacts/force" in chunks
    impacts, releases = _reference_intervals(run)
    texts = _texts(chunks, f"{prefix}/events/contacts")
    assert sum(_kind(x) == "impact" for x in texts) == impacts > 0
    assert sum(_kind(x) == "release" for x in texts) == releases > 0
    assert len(texts) == impacts + releases
    said, messages = _texts(chunks, f"{prefix}/events/log"), run.events["message"].to_list()
    assert len(said) == len(messages) and all(map(str.endswith, said, messages))


def test_one_recording_per_log_next_to_it(logs: dict[str, Path], tmp_path: Path) -> None:
    copies = [_copy(p, tmp_path / "in") for p in logs.values()]
    written = replay_logs(copies, out=None, analysis_dir=None)
    assert written == [p.with_suffix(".rrd") for p in copies]
    for log, rrd in zip(copies, written, strict=True):
        _verify(rrd)
        run = load_log(log)
        chunks = _read(rrd)
        assert all(p.startswith(run_prefix(run.run_id)) for p in chunks)
        _check_run(chunks, run)
        assert rr.chunk.RrdReader(rrd).blueprints(), "no default blueprint in the file"
    assert not list((tmp_path / "in").glob("*.partial"))


def test_several_logs_into_one_recording(logs: dict[str, Path], tmp_path: Path) -> None:
    target = tmp_path / "all.rrd"
    written = replay_logs(list(logs.values()), out=target, analysis_dir=None)
    assert written == [target]
    _verify(target)
    chunks = _read(target)
    runs = [load_log(p) for p in logs.values()]
    assert {p.split("/")[2] for p in chunks} == {run_prefix(r.run_id).split("/")[2] for r in runs}
    for run in runs:
        _check_run(chunks, run)
    collision = next(r for r in runs if len(r.bodies) == 2)
    px = chunks[f"{run_prefix(collision.run_id)}/series/momentum/px"]
    values = np.concatenate([b.column("Scalars:scalars").to_pylist() for b in px]).ravel()
    np.testing.assert_allclose(values, 1.0 * 2.0 + 2.0 * -1.0, atol=1e-9)  # conserved, zero


def test_log_events_carry_velocities(logs: dict[str, Path], tmp_path: Path) -> None:
    """First impact of a drop from 1 m (centre), r = 0.1 m: v_in = -sqrt(2 g 0.9) within 1 %;
    its release carries the analysis' e_velocity (one definition: `physics.e_velocity`)."""
    rrd = tmp_path / "drop.rrd"
    replay_logs([logs["drop"]], out=rrd, analysis_dir=None)
    run = load_log(logs["drop"])
    chunks = _read(rrd)
    path = f"{run_prefix(run.run_id)}/events/contacts"
    first = _texts(chunks, path)[0]
    v_in = float(first.split("v_in = ")[1].split(" ")[0])
    assert v_in == pytest.approx(-math.sqrt(2 * 9.81 * 0.9), rel=0.01)
    (_, release, e), details = _events(rrd, run.run_id)[1], _details(chunks, path)[1]
    assert release.startswith("release plane-ball: e_velocity = ")
    bounce = analyze_run(run).bounces.row(0, named=True)
    assert e == pytest.approx(bounce["e_velocity"], rel=1e-12)
    assert release.endswith(f"{bounce['e_velocity']:.3g}")
    e_energy = float(details.split("e_energy = ")[1].split(" ")[0])
    assert e_energy == pytest.approx(bounce["e_energy"], rel=1e-3)


def _events(rrd: Path, run_id: str) -> list[tuple[int, str, float | None]]:
    """(time in ns, text, e_velocity) of a run's impact and release events, read back."""
    out = []
    for batch in _read(rrd).get(f"{run_prefix(run_id)}/events/contacts", []):
        times = batch.column("sim_time").cast("int64").to_pylist()
        texts = [t[0] for t in batch.column("TextLog:text").to_pylist()]
        e = [x[0] if x else None for x in batch.column("e_velocity").to_pylist()]
        out += list(zip(times, texts, e, strict=True))
    return sorted(out)


def check_events_are_the_tables(logs: list[Path], results: Path, tmp_path: Path) -> int:
    """Replayed with the analysis folder, each run's impact and release events are the
    bounces' and collisions' rows: at their `impact_t_s` and `release_t_s` to the
    nanosecond, with their e_velocity (as the text says it, to 3 digits, as the report);
    replayed without it, the log's events at those times carry the same e. Returns the
    number of impacts compared."""
    tables = [pl.read_parquet(results / f"{name}.parquet") for name in ("bounces", "collisions")]
    rows = pl.concat(
        [t.select("run_id", "impact_t_s", "release_t_s", "e_velocity") for t in tables]
    ).filter(pl.col("impact_t_s").is_not_null())
    told = replay_logs(logs, out=tmp_path / "with-analysis.rrd", analysis_dir=results)[0]
    alone = replay_logs(logs, out=tmp_path / "from-log.rrd", analysis_dir=None)[0]
    compared = 0
    for run in map(load_log, logs):
        mine = rows.filter(pl.col("run_id") == run.run_id).sort("impact_t_s")
        shown = _events(told, run.run_id)
        want = []
        for row in mine.iter_rows(named=True):
            want.append((round(row["impact_t_s"] * 1e9), "impact", row["e_velocity"]))
            if row["release_t_s"] is not None:
                want.append((round(row["release_t_s"] * 1e9), "release", row["e_velocity"]))
        if not want:
            continue
        assert [(t, _kind(text), e) for t, text, e in shown] == sorted(want), run.run_id
        for _, text, e in shown:
            assert e is None or text.endswith(f"e_velocity = {e:.3g}"), text
        logged = {(t, _kind(text)): e for t, text, e in _events(alone, run.run_id)}
        for t, kind, e in want:
            assert (t, kind) in logged, (run.run_id, t, kind)
            if kind == "release" and e is not None:
                assert logged[(t, kind)] == pytest.approx(e, rel=1e-12), (run.run_id, t)
        compared += len(mine)
    return compared


def test_replay_and_report_agree_on_every_impact_of_the_golden_runs(tmp_path: Path) -> None:
    """The golden logs and their analysis (tests/golden/results): 10 impacts, drops on a
    plane and on a box's edge, two collisions."""
    logs = sorted((GOLDEN / "logs").glob("*.mcap"))
    assert check_events_are_the_tables(logs, GOLDEN / "results", tmp_path) == 10


@pytest.mark.slow
def test_replay_and_report_agree_on_every_impact_of_the_handouts_runs(tmp_path: Path) -> None:
    """The handout's experiments (experiments/*.toml), recorded, analyzed, replayed."""
    from impactlab.analyze.job import run_analysis

    results = record_runs(plan(sorted(EXPERIMENTS.glob("*.toml"))), tmp_path / "logs")
    logs = [r.path for r in results]
    run_analysis(logs, tmp_path / "results")
    assert check_events_are_the_tables(logs, tmp_path / "results", tmp_path) >= 20


def test_analysis_numbers_in_event_texts(logs: dict[str, Path], tmp_path: Path) -> None:
    run = load_log(logs["drop"])
    t = next(iter(run.bodies.values()))["t_s"].to_numpy()
    analysis = tmp_path / "results"
    analysis.mkdir()
    pl.DataFrame(
        {
            "run_id": [run.run_id, run.run_id, "another-run"],
            "bounce": [1, 2, 1],
            "impact_t_s": [t[100], t[400], t[5]],
            "release_t_s": [t[120], None, t[9]],
            "e_velocity": [0.91, 0.88, 0.1],
            "apex_m": [0.75, 0.6, 0.1],
        }
    ).write_parquet(analysis / "bounces.parquet")
    rrd = tmp_path / "drop.rrd"
    replay_logs([logs["drop"]], out=rrd, analysis_dir=analysis)
    _verify(rrd)
    chunks = _read(rrd)
    path = f"{run_prefix(run.run_id)}/events/contacts"
    texts = _texts(chunks, path)
    assert len(texts) == 3  # two impacts, one release (the second has none)
    assert texts == [  # short, one line each; every number one click away
        "impact bounce 1 plane-ball: e_velocity = 0.91",
        "release bounce 1 plane-ball: e_velocity = 0.91",
        "impact bounce 2 plane-ball: e_velocity = 0.88",
    ]
    details = _details(chunks, path)
    assert details[0] == "bounce = 1, e_velocity = 0.91, apex_m = 0.75"
    assert all(len(t) <= 60 and "\n" not in t for t in texts)
    np.testing.assert_array_equal(
        _times_ns(chunks[path]), run.bodies["ball"]["t_ns"].to_numpy()[[100, 120, 400]]
    )


def test_bad_inputs_one_line_each(
    logs: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    good = _copy(logs["drop"], tmp_path)
    text = tmp_path / "notes.mcap"
    text.write_text("not a log\n")
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    code = cli.main(["replay", str(text), str(good), str(empty), "-o", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert len(err) == 2
    assert err[0].startswith(f"impactlab: error: {text}: ")
    assert err[1].startswith(f"impactlab: error: {empty}: ")
    assert [p.name for p in (tmp_path / "out").iterdir()] == [good.with_suffix(".rrd").name]
    _verify(tmp_path / "out" / good.with_suffix(".rrd").name)
    assert not list(tmp_path.rglob("*.partial"))


def test_interrupted_conversion_leaves_nothing(
    logs: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def fail(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(recordings, "log_run", fail)
    with pytest.raises(KeyboardInterrupt):
        replay_logs([logs["drop"]], out=tmp_path / "x.rrd", analysis_dir=None)
    assert list(tmp_path.iterdir()) == []


def test_missing_analysis_folder_is_one_error(logs: dict[str, Path], tmp_path: Path, capsys):
    code = cli.main(["replay", str(logs["drop"]), "-o", str(tmp_path), "--analysis", "nope"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and err == ["impactlab: error: nope: analysis folder not found"]


@pytest.mark.slow
def test_replay_with_the_analysis_of_a_collision_that_never_happened(tmp_path: Path) -> None:
    """Stopped before the balls meet (the handout's Step 3 as written): the analysis has a
    collision row without an impact time; the replay shows no impact event, and no error."""
    from impactlab.analyze.job import run_analysis

    spec = tmp_path / "collision.toml"
    spec.write_text(COLLISION)
    (result,) = record_runs(plan([spec], overrides=["stop.max_time=0.05"]), tmp_path / "logs")
    analysis = run_analysis([result.path], tmp_path / "results")
    assert analysis.collisions.height == 1 and analysis.collisions["impact_t_s"][0] is None
    (rrd,) = replay_logs([result.path], out=tmp_path / "r.rrd", analysis_dir=tmp_path / "results")
    _verify(rrd)
    texts = _texts(_read(rrd), f"{run_prefix(load_log(result.path).run_id)}/events/contacts")
    assert not any(t.startswith("impact") for t in texts)


def test_series_are_named_by_the_reports_run_labels():
    """Runs in one recording are told apart by the report's label of each (one rule:
    `impactlab.logs.labels`): the experiment, and its sweep point in words and units."""
    runs = [
        load_log(GOLDEN / "logs" / f"{name}.mcap")
        for name in ("drop_bounces", "collision_sweep_point")
    ]
    assert recordings.run_labels(runs) == [
        "golden_drop_bounces",
        "golden_collision_sweep: ball2 mass = 2 kg",
    ]
    assert recordings.run_labels(runs[:1]) == [""]  # one run: nothing to tell apart
