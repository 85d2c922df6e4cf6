"""The model zoo of issue 35 for the tests (tests/models/): where benchmarks/zoo's oracle and
adapter are, the pinned models and their durations, and one model's run by MuJoCo and by
impactlab (`ZooRun`, made once per session by tests/models/conftest.py's `zoo_run`)."""

from __future__ import annotations

import contextlib
import dataclasses
import importlib.util
import os
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from paths import ROOT

ZOO = ROOT / "benchmarks" / "zoo"
sys.path.insert(0, str(ZOO))  # oracle.py and zoo.py import each other by name

import oracle  # noqa: E402
import zoo  # noqa: E402

OWN = "models/"  # the zoo's own models (benchmarks/zoo/models), named as zoo.find_models does
PINNED_S = {
    # simulated seconds per model: past the contacts each test is about, short enough that the
    # pinned subset stays within about a minute of one core
    "models/all_forces.xml": 0.5,
    "models/ball_hfield.xml": 0.5,
    "models/boxes_100.xml": 0.2,
    "models/cloth_drop.xml": 0.4,
    "models/damped_pendulum.xml": 0.6,
    "models/flexcomp_drop.xml": 0.4,  # MuJoCo's onset 0.284 s
    "models/gravcomp_actuated.xml": 0.4,
    "models/humanoid/humanoid.xml": 0.3,
    "models/humanoids_10.xml": 0.2,
    "models/jointed_boxes.xml": 0.5,  # the impact at 0.381 s
    "models/limits_violated.xml": 0.5,
    "models/massless_foot.xml": 0.5,  # MuJoCo's onset 0.440 s
    "models/mocap_platform.xml": 0.4,
    "models/nested_include/scene.xml": 0.4,
    "models/rope_drop.xml": 0.4,
    "models/sdf_torus.xml": 0.35,  # MuJoCo's onset 0.258 s
    "models/stacked_boxes.xml": 0.3,
    "models/sunk_robot.xml": 0.3,
    "models/tumbling_box.xml": 0.5,  # e_velocity 1.13 at 0.446 s
    # models that the pinned wheels ship (mujoco-core is a dependency; dm_control the
    # `models` extra)
    "mujoco/testdata/model.xml": 0.4,
    "dm_control/suite/quadruped.xml": 0.4,
    "dm_control/suite/ball_in_cup.xml": 0.5,
    "dm_control/suite/cheetah.xml": 0.4,
    "dm_control/suite/stacker.xml": 0.3,
}


def model_path(name: str) -> Path:
    """Where a pinned model lies: the zoo's own folder, or the installed package's."""
    if name.startswith(OWN):
        return ZOO / name
    package = name.split("/", 1)[0]
    spec = importlib.util.find_spec(package)
    if spec is None or spec.origin is None:
        pytest.fail(f"{package} is not installed: {name} needs it")
    return Path(spec.origin).parent.parent / name


@contextlib.contextmanager
def working_dir(folder: Path) -> Iterator[None]:
    """Run in `folder` (MuJoCo writes MUJOCO_LOG.TXT into the working folder on a warning)."""
    before = Path.cwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(before)


@dataclasses.dataclass(frozen=True)
class ZooRun:
    """One model at one logging stride, by MuJoCo and by impactlab.

    truth: the oracle's run, in the adapter's energy convention (zoo.SPRINGS_BOOKED_AS_WORK);
    side: impactlab's quantities read back from its log and analysis; folder: where the log,
    the analysis (`results/`, with report.md and figures) and `replay.rrd` are.
    """

    name: str
    path: Path
    truth: oracle.Run
    side: zoo.ImpactlabSide
    folder: Path

    @property
    def log(self) -> Path:
        (log,) = self.folder.glob("*.mcap")
        return log

    @property
    def report(self) -> str:
        return (self.folder / "results" / "report.md").read_text(encoding="utf-8")

    @property
    def rrd(self) -> Path:
        return self.folder / "replay.rrd"

    def failed_checks(self) -> list[zoo.Check]:
        """zoo.compare's checks that fail (the record-time ratio is measured, not checked)."""
        checks = zoo.compare(self.truth, self.side, bare_seconds=1.0, max_ratio=None)
        return [c for c in checks if c.passed is False]
