"""A disk that fills while recordings are written: one line naming the recording, exit 2, every
recording in the folder whole (`rerun rrd verify`), no temporary file left, the job stopped
(nothing more can be written)."""

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
disk, found, free, *logs = sys.argv[1:]
rrd = os.path.join(disk, "rrd")
first = impactlab("replay", logs[0], "-o", rrd)
before = files(disk)
fill(disk, int(free))
second = impactlab("replay", *logs, "-o", rrd)
one = impactlab("replay", *logs, "-o", os.path.join(disk, "all.rrd"))
rerun = os.path.join(os.path.dirname(sys.executable), "rerun")
after = files(disk)
verified = {name: subprocess.run([rerun, "rrd", "verify", os.path.join(disk, name)],
                                 capture_output=True).returncode for name in after}
json.dump({"first": first, "before": before, "second": second, "one": one, "after": after,
           "verified": verified}, open(found, "w"))
"""
)


@pytest.fixture(scope="module")
def logs(record_spec) -> list[Path]:
    spec = drop("full", z=0.3, max_time=0.4, sweep={"ball.mass": [1.0, 2.0, 3.0]})
    return record_spec("full", toml(spec))


@pytest.mark.parametrize("free", [0, 50_000, 300_000])
def test_a_full_disk_during_a_replay(tmp_path, logs, free):
    found = tmp_path / "found.json"
    disk = tmp_path / "disk"
    done = on_small_disk(disk, 4 << 20, SCRIPT, str(disk), str(found), str(free), *map(str, logs))
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(found.read_text())
    assert result["first"][0] == 0, result["first"]
    for key, target in (("second", None), ("one", disk / "all.rrd")):
        code, err = result[key]
        assert "Traceback" not in err, err
        errors = [line for line in err.splitlines() if line.startswith("impactlab: ")]
        assert code == 2 and len(errors) == 1, err
        assert errors[0].endswith(": cannot write: No space left on device"), errors
        if target is not None:
            assert errors[0] == f"impactlab: error: {target}: cannot write: No space left on device"
    after = result["after"]  # the recordings written before: as they were, or written again
    assert set(result["before"]) <= set(after)
    assert all(name.endswith(".rrd") and "/." not in name for name in after), after
    assert set(result["verified"].values()) == {0}, result["verified"]  # each one whole
