"""The MuJoCo versions impactlab declares (pyproject) are the ones it accepts; an older one,
installed by hand, is one error line. `.ci/run` runs the restitution tests on the oldest
declared version (3.3.7) as well as on the lock's pin."""

from __future__ import annotations

import re
import tomllib

import mujoco
import pytest
from paths import ROOT

from impactlab.errors import ImpactlabError
from impactlab.record.mujoco_version import MINIMUM, require_mujoco, version_tuple


@pytest.mark.parametrize(
    ("text", "parsed"),
    [("3.3.7", (3, 3, 7)), ("4.0.0", (4, 0, 0)), ("3.17.0", (3, 17, 0)), ("3.3.8rc1", (3, 3, 8))],
)
def test_version_tuple(text, parsed):
    assert version_tuple(text) == parsed


@pytest.mark.parametrize("version", ["3.2.7", "3.0.1", "2.3.7"])
def test_older_mujoco_is_one_clear_line(version):
    with pytest.raises(ImpactlabError) as info:
        require_mujoco(version)
    message = str(info.value)
    assert f"MuJoCo {version} is installed" in message and "mujoco>=3.3,<4.1" in message
    assert "\n" not in message


@pytest.mark.parametrize("version", ["3.3.0", "3.3.7", "3.17.0", "4.0.0"])
def test_declared_versions_are_accepted(version):
    require_mujoco(version)


def test_the_declared_range_is_the_checked_one():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    (spec,) = [d for d in project["dependencies"] if re.match(r"mujoco\b", d)]
    low = re.search(r">=([\d.]+)", spec).group(1)
    assert tuple(int(x) for x in low.split(".")) == MINIMUM
    assert version_tuple(mujoco.__version__) >= MINIMUM
