"""A disk that fills during an analysis: one line naming the output folder, exit 2, and the
previous analysis in the folder exactly as it was (nothing published, no staging left)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from disks import HELPERS, on_small_disk
from specs import drop, toml

pytestmark = pytest.mark.slow

SCRIPT = (
    HELPERS
    + """
disk, found, free, figures, *logs = sys.argv[1:]
res = os.path.join(disk, "res")
options = [] if figures == "figures" else ["--no-figures"]
first = impactlab("analyze", logs[0], "-o", res, *options)
before = files(res)
fill(disk, int(free))
second = impactlab("analyze", *logs, "-o", res, *options)
json.dump({"first": first, "before": before, "second": second, "after": files(res)},
          open(found, "w"))
"""
)


@pytest.fixture(scope="module")
def logs(record_spec) -> list[Path]:
    spec = drop("full", z=0.3, max_time=0.4, sweep={"ball.mass": [1.0, 2.0, 3.0]})
    return record_spec("full", toml(spec))


@pytest.mark.parametrize(
    ("free", "figures"),
    [
        (0, "figures"),
        (30_000, "figures"),
        (150_000, "figures"),
        (400_000, "figures"),
        (0, "tables"),
        (60_000, "tables"),
    ],
)
def test_a_full_disk_during_an_analysis(tmp_path, logs, free, figures):
    found = tmp_path / "found.json"
    done = on_small_disk(
        tmp_path / "disk",
        8 << 20,
        SCRIPT,
        str(tmp_path / "disk"),
        str(found),
        str(free),
        figures,
        *map(str, logs),
    )
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(found.read_text())
    assert result["first"][0] == 0, result["first"]
    code, err = result["second"]
    assert "Traceback" not in err, err
    errors = [line for line in err.splitlines() if line.startswith("impactlab: ")]
    disk = tmp_path / "disk"
    assert (code, errors) == (
        2,
        [f"impactlab: error: {disk}/res: cannot write: No space left on device"],
    )
    assert result["after"] == result["before"]  # the previous results, and only them
