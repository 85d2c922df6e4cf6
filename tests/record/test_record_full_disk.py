"""Record jobs on a disk too small for them: refused before anything is simulated when the
estimate (what every log carries, and its rows) does not fit; filled while writing (with
--allow-large), one line and exit 2 from the forked workers' job, never a traceback, only
complete logs left, and the job finished by running it again once there is room."""

from __future__ import annotations

import json

import pytest
from disks import HELPERS, on_small_disk
from specs import drop, toml

pytestmark = pytest.mark.slow

SPEC = toml(drop("full", max_time=0.05, sweep={"ball.mass": [1.0 + i for i in range(8)]}))
TRIES = 6  # the workers' tracebacks came about one try in two

SCRIPT = (
    HELPERS
    + """
from pathlib import Path
from impactlab.logs.status import complete_metadata
disk, found, spec = sys.argv[1:]
logs = os.path.join(disk, "logs")
fill(disk, 100_000)  # room for two of the eight logs, more than all their rows take
refused = impactlab("record", spec, "-o", logs)
listed = sorted(files(disk))  # every file but the filler
tries = []
for _ in range(TRIES):
    code, err = impactlab("record", spec, "-o", logs, "--allow-large")
    names = sorted(os.listdir(logs))
    whole = [complete_metadata(Path(logs, n)) is not None for n in names]
    tries.append([code, err, names, whole])
os.remove(os.path.join(disk, "filler"))
again = impactlab("record", spec, "-o", logs)
json.dump({"refused": refused, "listed": listed, "tries": tries, "again": again,
           "finally": sorted(os.listdir(logs))}, open(found, "w"))
""".replace("TRIES", str(TRIES))
)


def test_a_record_job_on_a_disk_too_small(tmp_path):
    spec = tmp_path / "full.toml"
    spec.write_text(SPEC)
    found = tmp_path / "found.json"
    disk = tmp_path / "disk"
    done = on_small_disk(disk, 1 << 20, SCRIPT, str(disk), str(found), str(spec))
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(found.read_text())
    code, err = result["refused"]
    assert code == 2 and err.startswith(f"impactlab: error: {disk}/logs: not enough space: about")
    assert len(err.splitlines()) == 1 and result["listed"] == []
    for code, err, names, whole in result["tries"]:
        assert "Traceback" not in err, err
        assert code == 2 and len(err.splitlines()) == 1, err
        assert "cannot write the log: No space left on device" in err
        assert all(name.endswith(".mcap") for name in names) and all(whole), names
    code, err = result["again"]
    assert code == 0, err
    assert len(result["finally"]) == 8 and all(n.endswith(".mcap") for n in result["finally"])
