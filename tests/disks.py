"""A small disk for the tests: a tmpfs of a chosen size, mounted in a mount namespace of its own
(invisible outside, gone when the command ends), where the machine allows one.

`on_small_disk(folder, size, script)` runs a Python `script` there, with `folder` a fresh empty
disk of `size` bytes; the script reaches the rest of the file system as usual, so it leaves its
findings outside the disk. `HELPERS` defines functions for such scripts: `fill(folder, free)`
fills a disk until `free` bytes are left, `impactlab(*args)` runs the command line (exit
code, stderr), `files(folder)` hashes every file below a folder."""

from __future__ import annotations

import functools
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

MOUNT = 'mount -t tmpfs -o size="$1" tmpfs "$2" && shift 2 && exec "$@"'


@functools.cache
def _prefix() -> list[str] | None:
    """The command prefix that mounts a tmpfs (`MOUNT`), or None where none can be."""
    if shutil.which("unshare") is None:
        return None
    for flags in (["-m"], ["-r", "-m"]):
        prefix = ["unshare", *flags, "--propagation", "private", "sh", "-c", MOUNT, "sh"]
        probe = [*prefix, "64k", "/tmp", "true"]
        try:
            if subprocess.run(probe, capture_output=True, timeout=60).returncode == 0:
                return prefix
        except OSError:
            return None
    return None


def on_small_disk(
    folder: Path, size: int, script: str, *args: str, timeout: float = 600
) -> subprocess.CompletedProcess[str]:
    """Run `python -c script args...` with `folder` (created) a disk of `size` bytes."""
    prefix = _prefix()
    if prefix is None:
        pytest.skip("no mount namespace here (unshare needs root or user namespaces)")
    folder.mkdir(parents=True, exist_ok=True)
    command = [*prefix, str(size), str(folder), sys.executable, "-c", script, *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=timeout)


HELPERS = """
import hashlib, json, os, subprocess, sys

def fill(folder, free):
    with open(os.path.join(folder, "filler"), "wb") as stream:
        while (left := os.statvfs(folder).f_bavail * os.statvfs(folder).f_frsize) > free:
            stream.write(bytes(min(left - free, 1 << 20)))
            stream.flush()

def impactlab(*args):
    done = subprocess.run(
        [sys.executable, "-m", "impactlab", *args], capture_output=True, text=True
    )
    return done.returncode, done.stderr

def files(folder):
    return {
        os.path.relpath(os.path.join(d, f), folder): hashlib.sha256(
            open(os.path.join(d, f), "rb").read()
        ).hexdigest()
        for d, _, names in os.walk(folder)
        for f in names
        if f != "filler"
    }
"""
"""Functions for the scripts run on a small disk (put them first in the script)."""
