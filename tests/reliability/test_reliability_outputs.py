"""The analysis' output folder: killed at any point, re-run with fewer logs, or written by two
analyses at once, it holds complete files only, and exactly one analysis' set of them.

A file under its final name is complete (Parquet, JSON, PNG and Markdown are each read back);
every file impactlab wrote is listed in the folder's manifest, so the next analysis removes
what it does not write again; the user's own files are never touched.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import matplotlib.image
import polars as pl
import pytest
from specs import drop, toml

from impactlab.cli import main

MANIFEST = ".impactlab-analysis.json"  # documented in docs/reliability.md
STAGING_PREFIX = ".impactlab-staging-"

SPEC = toml(
    drop(
        "drops",
        z=0.3,
        max_time=0.5,
        sweep={"ball.pos": [[0.0, 0.0, 0.25], [0.0, 0.0, 0.3], [0.0, 0.0, 0.35]]},
    )
)
USER_FILES = {"notes.md": "my notes\n", "figures/mine.png": "not even a PNG"}


@pytest.fixture(scope="module")
def logs(record_spec) -> list[Path]:
    return record_spec("drops", SPEC)


def add_user_files(out: Path) -> None:
    for name, text in USER_FILES.items():
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_text(text)


def read_manifest(out: Path) -> list[str]:
    """The files the manifest says impactlab wrote ([] without one)."""
    path = out / MANIFEST
    return json.loads(path.read_text())["files"] if path.exists() else []


def visible(out: Path) -> set[str]:
    """Every file a person sees in the folder (not the hidden bookkeeping and staging)."""
    return {
        p.relative_to(out).as_posix()
        for p in out.rglob("*")
        if p.is_file() and not any(part.startswith(".") for part in p.relative_to(out).parts)
    }


def assert_complete(path: Path) -> None:
    """The file reads back whole as what its name says it is."""
    if path.suffix == ".parquet":
        pl.read_parquet(path)
    elif path.suffix == ".json":
        json.loads(path.read_text())
    elif path.suffix == ".png":
        assert path.read_bytes()[-8:] == b"IEND\xaeB`\x82", path  # the PNG's last chunk
        matplotlib.image.imread(path)
    elif path.suffix == ".md":
        assert path.read_text().endswith("\n"), path
    elif path.suffix == ".html":
        assert path.read_text().endswith("</html>\n"), path
    else:
        raise AssertionError(f"unexpected output {path}")


def assert_consistent(out: Path, *, reports: tuple[str, ...] = ()) -> set[str]:
    """Complete files, all listed in the manifest (or the user's); returns impactlab's files."""
    ours = visible(out) - set(USER_FILES)
    assert ours <= set(read_manifest(out)), sorted(ours - set(read_manifest(out)))
    for name in ours:
        assert_complete(out / name)
    for name, text in USER_FILES.items():
        assert (out / name).read_text() == text, name
    if reports and (out / "report.md").exists():
        assert (out / "report.md").read_text() in reports
    return ours


@pytest.mark.slow
def test_rerun_with_fewer_logs_removes_what_it_does_not_write_again(tmp_path, capsys, logs):
    out = tmp_path / "results"
    assert main(["analyze", *map(str, logs), "-o", str(out)]) == 0
    add_user_files(out)
    first = assert_consistent(out)
    assert sum(name.startswith("figures/") and logs[2].stem in name for name in first) >= 1

    assert main(["analyze", str(logs[0]), "-o", str(out)]) == 0
    second = assert_consistent(out)
    assert not any(log.stem in name for log in logs[1:] for name in second)  # stale: gone
    assert second == set(read_manifest(out))  # exactly what this analysis wrote
    assert pl.read_parquet(out / "runs.parquet").height == 1
    assert logs[1].stem not in (out / "report.md").read_text()
    assert not list(out.glob(f"{STAGING_PREFIX}*"))
    capsys.readouterr()


def test_the_manifest_never_names_a_file_outside_the_folder(tmp_path, capsys, logs):
    out = tmp_path / "results"
    out.mkdir()
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    names = ["../victim.txt", str(victim), "", "figures/../../victim.txt", 7]
    (out / MANIFEST).write_text(json.dumps({"files": names}))
    assert main(["analyze", str(logs[0]), "-o", str(out)]) == 0
    assert victim.read_text() == "keep me"
    capsys.readouterr()


ZYGOTE = """
import json, os, signal, sys, time
import impactlab.analyze.job, impactlab.analyze.report.figures, impactlab.analyze.report.run_figures
from impactlab.cli import main
for line in sys.stdin:
    request = json.loads(line)
    start = time.monotonic()
    pid = os.fork()
    if pid == 0:  # the analysis, in a fresh child of this already-imported process
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.dup2(null, 2)
        os._exit(main(request["argv"]))
    if request["kill_after"] is not None:
        time.sleep(request["kill_after"])
        os.kill(pid, signal.SIGKILL)
    _, status = os.waitpid(pid, 0)
    print(json.dumps([status, time.monotonic() - start]), flush=True)
"""


class Zygote:
    """A process that has imported impactlab and forks one analysis per request, so that many
    can be killed at chosen moments without paying for the imports each time."""

    def __init__(self) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-c", ZYGOTE], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )

    def run(self, argv: list[str], kill_after: float | None = None) -> tuple[int, float]:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(json.dumps({"argv": argv, "kill_after": kill_after}) + "\n")
        self.proc.stdin.flush()
        status, seconds = json.loads(self.proc.stdout.readline())
        return status, seconds

    def close(self) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        self.proc.wait(timeout=30)


KILL_POINTS = 14


@pytest.mark.slow
def test_killed_at_many_points(tmp_path, logs):
    """SIGKILL at evenly spread moments of an analysis that replaces an earlier one: the folder
    holds complete files only, each listed in the manifest; the next run cleans up."""
    zygote = Zygote()
    try:
        old = tmp_path / "old"
        status, _ = zygote.run(["analyze", str(logs[1]), str(logs[2]), "-o", str(old)])
        assert status == 0
        add_user_files(old)
        ref = tmp_path / "ref"
        new_logs = [str(logs[0]), str(logs[1])]
        status, seconds = zygote.run(["analyze", *new_logs, "-o", str(ref)])
        assert status == 0
        reports = ((old / "report.md").read_text(), (ref / "report.md").read_text())
        out = tmp_path / "results"
        killed = 0
        for k in range(1, KILL_POINTS + 1):
            shutil.rmtree(out, ignore_errors=True)
            # linked, not copied: the files the earlier analysis wrote, not copies of them
            # (a copy's files are not provably impactlab's: they are never removed)
            shutil.copytree(old, out, copy_function=os.link)
            status, _ = zygote.run(
                ["analyze", *new_logs, "-o", str(out)], kill_after=seconds * k / (KILL_POINTS + 1)
            )
            killed += status != 0
            assert_consistent(out, reports=reports)
        assert killed >= KILL_POINTS // 3  # many runs were really cut short
        status, _ = zygote.run(["analyze", *new_logs, "-o", str(out)])  # after the last kill
        assert status == 0
        assert assert_consistent(out) == visible(ref)
        assert (out / "report.md").read_text() == reports[1]
        assert not list(out.glob(f"{STAGING_PREFIX}*"))  # the killed runs' staging removed
    finally:
        zygote.close()


@pytest.mark.slow
def test_two_analyses_into_one_folder_at_once(tmp_path, logs):
    out = tmp_path / "results"
    out.mkdir()
    add_user_files(out)
    sets = {"three": [str(p) for p in logs], "one": [str(logs[0])]}
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "impactlab", "analyze", *paths, "-o", str(out)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        for paths in sets.values()
    ]
    for proc in procs:
        _, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err
    ours = assert_consistent(out)
    assert ours == set(read_manifest(out))
    runs = pl.read_parquet(out / "runs.parquet")["file"].to_list()
    assert sorted(runs) in (sorted(sets["three"]), sets["one"])  # one analysis' set, whole
    summary = json.loads((out / "summary.json").read_text())
    assert sorted(r["file"] for r in summary["runs"]) == sorted(runs)
    report = (out / "report.md").read_text() + (out / "report-appendix.md").read_text()
    for name in ours:
        if name.startswith("figures/") and name.endswith(".png"):
            assert name in report, name  # every figure written is shown
    assert all(Path(log).stem in report for log in runs)
    assert not any(Path(log).stem in report for log in set(sets["three"]) - set(runs))
    assert not list(out.glob(f"{STAGING_PREFIX}*"))
