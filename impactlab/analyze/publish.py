"""An analysis' files replace the previous ones as a set: staged, then published under a lock.

Every file of an analysis is written into a private staging folder inside the output folder
(`staged`), under its final relative path. Only when all are written does `publish` move them
into place, one rename each, and remove the files the previous analysis wrote there that this
one did not (a figure of a run that is no longer analyzed). What impactlab wrote is recorded in
a manifest (`MANIFEST`) listing relative paths, so a user's own files in the folder are never
touched. The manifest is widened before any file moves and narrowed after, so whatever
interrupts a publish, every file impactlab left in the folder is listed, and the next analysis
removes it if it does not write it again.

Publishing holds an exclusive lock (`LOCK`, `fcntl.flock`): two analyses into one folder
publish one after the other, and the folder ends with the complete set of the one that
published last. A staging folder left by a killed analysis is removed by the next one (its
owner's lock is gone).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import tempfile
import time
from collections.abc import Iterator, Sequence
from pathlib import Path, PurePosixPath

from impactlab.files import OutputError, write_json

MANIFEST = ".impactlab-analysis.json"
LOCK = ".impactlab-analysis.lock"
STAGING_PREFIX = ".impactlab-staging-"
OWNER = ".owner"
ABANDONED_AFTER_S = 60.0  # a staging folder without its owner's lock file, older than this


@contextlib.contextmanager
def staged(out: Path) -> Iterator[Path]:
    """A private staging folder inside `out` (created), removed when the block ends.

    Staging folders that analyses killed earlier left behind are removed first.

    Raises:
        OutputError: it cannot be created.
    """
    remove_abandoned(out)
    try:
        stage = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=out))
        # the owner file appears under its name only once locked: another analysis cleaning
        # up never finds it unlocked while this one lives
        claim = stage / f"{OWNER}.{os.getpid()}"
        owner = open(claim, "w")  # noqa: SIM115 (held until the block ends)
        fcntl.flock(owner, fcntl.LOCK_EX)  # held while this process lives
        os.replace(claim, stage / OWNER)
    except OSError as exc:
        raise OutputError(out, f"cannot write there: {exc.strerror or exc}") from None
    try:
        yield stage
    finally:
        shutil.rmtree(stage, ignore_errors=True)
        owner.close()


def remove_abandoned(out: Path) -> None:
    """Remove the staging folders of analyses that no longer run."""
    for stage in out.glob(f"{STAGING_PREFIX}*"):
        if not stage.is_dir() or stage.is_symlink():
            continue
        try:
            with open(stage / OWNER) as owner:
                fcntl.flock(owner, fcntl.LOCK_EX | fcntl.LOCK_NB)  # free: the owner is gone
        except FileNotFoundError:  # killed before its lock file existed, or being created
            with contextlib.suppress(OSError):
                if time.time() - stage.stat().st_mtime < ABANDONED_AFTER_S:
                    continue
        except OSError:  # locked: a live analysis
            continue
        shutil.rmtree(stage, ignore_errors=True)


def publish(stage: Path, out: Path, files: Sequence[Path]) -> list[Path]:
    """Move the staged `files` into `out` and remove what the previous analysis left there.

    Args:
        stage: the staging folder (`staged`).
        out: the output folder.
        files: the files written, all inside `stage`.

    Returns:
        The files' final paths, in the order of `files` (each once).

    Raises:
        OutputError: a file cannot be moved into place (e.g. a folder is in its way).
    """
    files = list(dict.fromkeys(files))  # two runs of one id draw one figure file, once
    names = [str(PurePosixPath(*Path(f).relative_to(stage).parts)) for f in files]
    with _locked(out / LOCK):
        previous = read_manifest(out)
        _write_manifest(out, sorted(set(previous) | set(names)))
        for name, staged_file in zip(names, files, strict=True):
            target = out / name
            try:
                target.parent.mkdir(parents=True, exist_ok=True)
                os.replace(staged_file, target)
            except OSError as exc:
                raise OutputError(target, f"cannot write: {exc.strerror or exc}") from None
        for name in sorted(set(previous) - set(names)):
            _remove(out, name)
        _write_manifest(out, sorted(names))
    return [out / name for name in names]


def read_manifest(out: Path) -> list[str]:
    """The files (relative paths) the last analysis wrote into `out`; [] without a manifest.

    Entries that could name anything outside `out` (absolute, `..`) are ignored: the
    manifest is only ever a list of what impactlab may remove.
    """
    try:
        document = json.loads((out / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    names = document.get("files", []) if isinstance(document, dict) else []
    return [n for n in names if isinstance(n, str) and _inside(n)]


def _inside(name: str) -> bool:
    path = PurePosixPath(name)
    return bool(name) and not path.is_absolute() and ".." not in path.parts and "\\" not in name


def _write_manifest(out: Path, names: Sequence[str]) -> None:
    write_json(
        out / MANIFEST,
        {"written_by": "impactlab analyze", "files": list(names)},
    )


def _remove(out: Path, name: str) -> None:
    """Remove one file impactlab wrote (a regular file only), and folders it leaves empty."""
    target = out / name
    if target.is_symlink() or not target.is_file():
        return
    with contextlib.suppress(OSError):
        target.unlink()
    parent = target.parent
    while parent != out and out in parent.parents:
        try:
            parent.rmdir()  # only when empty
        except OSError:
            break
        parent = parent.parent


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    try:
        handle = open(path, "a")  # noqa: SIM115 (closed below)
    except OSError as exc:
        raise OutputError(path.parent, f"cannot write there: {exc.strerror or exc}") from None
    with handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
