"""A pip install does what a clone does: the wheel, installed in a fresh venv, used from an
empty folder.

`python -m build` makes the sdist and, from the unpacked sdist, the wheel (so both are
checked); the wheel goes into a new venv outside the tree with the lock's pins (pip's
configured index, no other network), and the commands that read package data run from an
empty folder with no PYTHONPATH: `impactlab contact` (the restitution tables), a model tuned
with `impactlab contact MODEL.xml`, `impactlab calibrate --grid quick`, `impactlab lab` (the
packaged experiments), `impactlab examples` and a command of docs/experiments.md on the copies. The checkout
tools (`impactlab.golden`, `impactlab.proto.generate`) answer in one line there, and a type
checker reads the installed package's types (`py.typed`).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest
from paths import ROOT

pytestmark = pytest.mark.slow

ALONE = [
    "contact",
    "--restitution",
    "0.8",
    "--radius",
    "0.05",
    "--speed",
    "0.5..4",
    "--timestep",
    "1e-5",
]
BALL = """<mujoco model="user">
  <option timestep="1e-5" integrator="implicitfast"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="ball" pos="0 0 0.6"><freejoint/><geom name="ballgeom" type="sphere" size="0.05" mass="0.2"/></body>
  </worldbody>
</mujoco>
"""


def _env() -> dict[str, str]:
    """The environment of a user's shell: nothing pointing into this checkout, and bytecode
    written as usual (the wheel is installed with --no-compile: the first command compiles
    what it imports into the venv, the next ones and their spawned workers reuse it)."""
    drop = ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONDONTWRITEBYTECODE")
    return {k: v for k, v in os.environ.items() if k not in drop}


def run(args: list[str], cwd: Path, *, check: bool = True) -> subprocess.CompletedProcess[str]:
    done = subprocess.run(args, cwd=cwd, env=_env(), capture_output=True, text=True, timeout=900)
    if check:
        assert done.returncode == 0, f"{args}: exit {done.returncode}\n{done.stdout}\n{done.stderr}"
    assert "Traceback" not in done.stderr, done.stderr
    return done


@pytest.fixture(scope="module")
def dist(tmp_path_factory) -> Path:
    """The sdist and the wheel built from it."""
    out = tmp_path_factory.mktemp("dist")
    run([sys.executable, "-m", "build", "--outdir", str(out), str(ROOT)], out)
    return out


@pytest.fixture(scope="module")
def venv(dist, tmp_path_factory) -> Path:
    """A fresh venv with the wheel and its dependencies at the lock's pins; its bin/."""
    where = tmp_path_factory.mktemp("venv")
    run([sys.executable, "-m", "venv", str(where)], where)
    bin_dir = where / "bin"
    (wheel,) = dist.glob("impactlab-*.whl")
    pip = [str(bin_dir / "python"), "-m", "pip", "install", "--no-compile", "-q"]
    run([*pip, "-c", str(ROOT / "requirements.lock"), str(wheel)], where)
    return bin_dir


@pytest.fixture
def empty(tmp_path) -> Path:
    folder = tmp_path / "work"
    folder.mkdir()
    return folder


def test_the_wheel_holds_the_package_data_and_metadata(dist):
    (wheel,) = dist.glob("impactlab-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for table in ("restitution_table.json", "restitution_table_rk4.json"):
        assert f"impactlab/contact/{table}" in names
    specs = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "experiments").rglob("*.toml"))
    assert sorted(n.removeprefix("impactlab/") for n in names if "/experiments/" in n) == specs
    assert {"impactlab/py.typed", "impactlab/proto/impactlab_pb2.pyi"} <= names
    modules = {p.relative_to(ROOT).as_posix() for p in (ROOT / "impactlab").rglob("*.py")}
    assert modules - names == set()  # every module of every package (setup.py finds them)
    (meta,) = [n for n in names if n.endswith(".dist-info/METADATA")]
    text = zipfile.ZipFile(wheel).read(meta).decode()
    assert "License-Expression: MIT" in text and "Author: impactlab developers" in text
    assert "Requires-Dist: mujoco<4.1,>=3.3" in text
    assert "Classifier: Typing :: Typed" in text
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    assert not any(n.startswith(("tests/", "experiments/", "docs/")) for n in names)


def test_the_sdist_holds_what_the_tests_need(dist):
    (sdist,) = dist.glob("impactlab-*.tar.gz")
    with tarfile.open(sdist) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
    need = {
        "LICENSE",
        "requirements.lock",
        "tests/conftest.py",
        "tests/paths.py",
        "tests/e2e/test_wheel.py",
        "tests/golden/specs/drop_restitution.toml",
        "tests/golden/logs/drop_restitution.mcap",
        "tests/golden/results/bounces.parquet",
        "experiments/drop_restitution.toml",
        "schemas/impactlab.proto",
        "docs/python-api.md",
        "docs/report-restitution.png",
    }
    assert need <= names, sorted(need - names)


def test_the_sdists_tests_run_from_it(dist, tmp_path):
    """Unpacked, the sdist is a checkout: the tests of its golden data, experiments, schemas
    and README run there (with this interpreter, the sdist's impactlab first on the path)."""
    (sdist,) = dist.glob("impactlab-*.tar.gz")
    with tarfile.open(sdist) as tar:
        tar.extractall(tmp_path, filter="data")
    (tree,) = tmp_path.glob("impactlab-*")
    tests = [
        "e2e/test_golden.py",
        "e2e/test_examples.py",
        "logs/test_schemas.py",
        "e2e/test_readme.py",
    ]
    env = {**_env(), "PYTHONPATH": str(tree)}
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-m", "slow or not slow"]
        + [f"tests/{t}" for t in tests],
        cwd=tree,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stdout[-3000:]
    assert " passed" in done.stdout and " skipped" not in done.stdout


def test_contact_designs_and_tunes_a_model_from_an_empty_folder(venv, empty):
    done = run(
        [str(venv / "impactlab"), *ALONE],
        empty,
    )
    assert "<pair" in done.stdout and "solref" in done.stdout
    (empty / "ball.xml").write_text(BALL)
    done = run(
        [
            str(venv / "impactlab"),
            "contact",
            "ball.xml",
            "--pair",
            "ballgeom/floor=0.8",
            "-o",
            "t.xml",
        ],
        empty,
    )
    assert "<pair" in (empty / "t.xml").read_text()


def test_calibrate_from_an_empty_folder(venv, empty):
    """The shipped calibration experiment (cut to one target) from the installed package."""
    done = run([str(venv / "impactlab"), "calibrate", "--targets", "0.8"], empty)
    out = empty / "calibration" / "results"
    for name in ("report.md", "calibration.parquet", "bounces.parquet", "collisions.parquet"):
        assert (out / name).is_file(), name
    assert "## Calibration: e against its target" in (out / "report.md").read_text()
    assert "every impact meets its bound" in done.stdout
    # a mistake: one line, exit 2, and no folder left behind
    bad = run(
        [str(venv / "impactlab"), "calibrate", "-o", "cal2", "--targets", "5"], empty, check=False
    )
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1, bad.stderr
    assert not (empty / "cal2").exists()


def test_lab_runs_the_packaged_experiments_from_an_empty_folder(venv, empty):
    done = run([str(venv / "impactlab"), "lab"], empty)
    assert "running the handout's experiments shipped with impactlab" in done.stdout + done.stderr
    results = empty / "lab-output" / "results"
    appendix = (results / "report-appendix.md").read_text()
    assert (results / "report.html").is_file() and "## Replays" in appendix
    logs = sorted((empty / "lab-output" / "logs").rglob("*.mcap"))
    assert any("drop_restitution" in p.name for p in logs)
    assert len(sorted((results / "replays").glob("*.rrd"))) == len(logs) > 7
    assert f"report: lab-output{os.sep}results{os.sep}report.md" in done.stdout


def test_examples_copies_the_specs_and_the_readme_commands_work_on_them(venv, empty):
    run([str(venv / "impactlab"), "examples"], empty)
    assert (empty / "experiments" / "drop.toml").read_bytes() == (
        ROOT / "experiments" / "drop.toml"
    ).read_bytes()
    done = run(
        [str(venv / "impactlab"), "record", "experiments/drop.toml", "--set", "ball.mass=2"], empty
    )
    assert len(list((empty / "logs").glob("*.mcap"))) == 3, done.stdout


def test_checkout_tools_answer_in_one_line(venv, empty):
    python = str(venv / "python")
    for module in ("impactlab.golden", "impactlab.proto.generate"):
        done = run([python, "-m", module], empty, check=False)
        assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
        assert "checkout" in done.stderr


def test_a_type_checker_reads_the_installed_types(venv, empty):
    """mypy with the venv's site-packages (not this checkout): the API is typed there too."""
    (empty / "use.py").write_text(
        "import impactlab\n"
        "import impactlab.analyze\n"
        "result = impactlab.analyze(['logs'], figurez=True)\n"
        "reveal_type(impactlab.load('a.mcap'))\n"
    )
    done = run(
        [sys.executable, "-m", "mypy", "--python-executable", str(venv / "python"), "use.py"],
        empty,
        check=False,
    )
    assert done.returncode == 1, done.stdout
    assert 'Unexpected keyword argument "figurez" for "analyze"' in done.stdout
    assert 'Revealed type is "impactlab.logs.load.RunLog"' in done.stdout
