"""An analysis' files replace the previous ones as a set: staged, then published under a lock."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import shutil
import stat
import tempfile
import time
from collections.abc import Iterator, Sequence
from pathlib import Path, PurePosixPath

from impactlab.files import (
    NOT_TEXT,
    OutputError,
    check_writable,
    full_disk_error,
    is_text,
    read_regular,
    write_json,
)

MANIFEST = ".impactlab-analysis.json"
LOCK = ".impactlab-analysis.lock"
STAGING_PREFIX = ".impactlab-staging-"
OWNER = ".owner"
ABANDONED_AFTER_S = 60.0  # a staging folder without its owner's lock file, older than this
MAX_MANIFEST_BYTES = 256 << 20  # a sweep of 100,000 runs with figures lists about 100 MB


@contextlib.contextmanager
def staged(out: Path) -> Iterator[Path]:
    """A private staging folder inside `out` (checked, made), removed when the block ends:
    every file of an analysis is written there, under its final relative path, until
    `publish`; a full disk meanwhile is an `OutputError` naming `out`.

    Staging folders that analyses killed earlier left behind are removed first (their
    owner's lock is gone).

    Raises:
        OutputError: `out` cannot be written (`check_writable`), or its name is not text.
    """
    if not is_text(out):  # its paths go into the tables and the report
        raise OutputError(out, NOT_TEXT)
    check_writable(out)
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
        with full_disk_error(out):
            yield stage
    finally:
        shutil.rmtree(stage, ignore_errors=True)
        owner.close()


def remove_abandoned(out: Path) -> None:
    """Remove the staging folders of analyses that no longer run."""
    for stage in out.glob(f"{STAGING_PREFIX}*"):
        if not stage.is_dir() or stage.is_symlink():
            continue
        try:  # never waiting, never following a link (the folder may come from elsewhere)
            owner = os.open(stage / OWNER, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW)
            try:
                fcntl.flock(owner, fcntl.LOCK_EX | fcntl.LOCK_NB)  # free: the owner is gone
            finally:
                os.close(owner)
        except FileNotFoundError:  # killed before its lock file existed, or being created
            with contextlib.suppress(OSError):
                if time.time() - stage.stat().st_mtime < ABANDONED_AFTER_S:
                    continue
        except OSError:  # locked: a live analysis
            continue
        shutil.rmtree(stage, ignore_errors=True)


def publish(stage: Path, out: Path, files: Sequence[Path]) -> list[Path]:
    """Move the staged `files` into `out` and remove what the previous analysis left there
    (a figure of a run no longer analyzed), holding an exclusive lock (`LOCK`): two analyses
    into one folder publish one after the other, and it ends with the set of the last.

    Every folder on the way is reached without following a link (one in the way is refused
    before anything moves). The manifest lists each file with its identity (`_identity`), and
    is widened before any file moves and narrowed after, so whatever interrupts a publish,
    every file it left is listed. A file is removed only when its identity is the one listed:
    what impactlab wrote there, never a file a manifest from elsewhere names.

    Args:
        stage: the staging folder (`staged`).
        out: the output folder.
        files: the files written, all inside `stage`.

    Returns:
        The files' final paths, in the order of `files` (each once).

    Raises:
        OutputError: a file cannot be moved into place (a link, file or folder in the way).
    """
    files = list(dict.fromkeys(files))  # two runs of one id draw one figure file, once
    names = [PurePosixPath(*Path(f).relative_to(stage).parts).parts for f in files]
    with _locked(out / LOCK):
        for parent in dict.fromkeys(name[:-1] for name in names):  # before anything moves
            try:
                os.close(_folder(out, parent, create=True))
            except OSError as exc:
                problem = "a link or a file, not a folder" if exc.errno in LINK_ERRORS else exc
                raise OutputError(out / exc.filename, f"cannot write there: {problem}") from None
        previous = read_manifest(out)
        written = {"/".join(n): [_identity(os.lstat(f))] for n, f in zip(names, files, strict=True)}
        widened = {n: previous.get(n, []) + written.get(n, []) for n in {*previous, *written}}
        _write_manifest(out, widened)
        for name, staged_file in zip(names, files, strict=True):
            folder = _folder(out, name[:-1])
            try:
                os.replace(staged_file, name[-1], dst_dir_fd=folder)
            except OSError as exc:
                target = out.joinpath(*name)
                raise OutputError(target, f"cannot write: {exc.strerror or exc}") from None
            finally:
                os.close(folder)
        for stale in sorted(previous.keys() - written.keys()):
            _remove(out, PurePosixPath(stale).parts, previous[stale])
        _write_manifest(out, written)
    return [out.joinpath(*name) for name in names]


Identity = list[int]
"""A file's inode, size and modification time (ns): what a file impactlab wrote keeps when it
is renamed, and what a manifest made elsewhere cannot foretell (a copied folder's inodes)."""


def _identity(info: os.stat_result) -> Identity:
    return [info.st_ino, info.st_size, info.st_mtime_ns]


def read_manifest(out: Path) -> dict[str, list[Identity]]:
    """The files (relative paths, with their identities) the last analysis wrote into `out`;
    {} without a readable manifest. Entries that could name anything outside `out` (absolute,
    `..`) or are not well formed are ignored: the manifest is untrusted."""
    try:
        document = json.loads(read_regular(out / MANIFEST, MAX_MANIFEST_BYTES))
        files = document["files"]
        listed = files.items()
    except (OSError, ValueError, TypeError, KeyError, AttributeError, RecursionError):
        return {}
    return {
        "/".join(PurePosixPath(name).parts): [
            i for i in ids if isinstance(i, list) and len(i) == 3 and {type(n) for n in i} == {int}
        ]
        for name, ids in listed
        if _inside(name) and isinstance(ids, list)
    }


def _inside(name: object) -> bool:
    """Whether a manifest's entry is a relative path inside the folder (no `..`, no NUL)."""
    if not isinstance(name, str) or "\0" in name or "\\" in name:
        return False
    path = PurePosixPath(name)
    return bool(path.parts) and not path.is_absolute() and ".." not in path.parts


def _write_manifest(out: Path, files: dict[str, list[Identity]]) -> None:
    write_json(
        out / MANIFEST, {"written_by": "impactlab analyze", "files": dict(sorted(files.items()))}
    )


def _folder(out: Path, parts: tuple[str, ...], *, create: bool = False) -> int:
    """The folder `parts` below `out`, opened (the caller closes it) without following a link
    on the way; made when `create`.

    Raises:
        OSError: missing, or a link or a file in the way; its filename the path below `out`.
    """
    fd, reached = os.open(out, os.O_RDONLY | os.O_DIRECTORY), ""
    try:
        for part in parts:
            reached += f"/{part}" if reached else part
            if create:
                with contextlib.suppress(FileExistsError):
                    os.mkdir(part, dir_fd=fd)
            fd, parent = os.open(part, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW, dir_fd=fd), fd
            os.close(parent)
    except OSError as exc:
        os.close(fd)
        raise OSError(exc.errno, exc.strerror, reached) from None
    return fd


def _remove(out: Path, parts: tuple[str, ...], identities: list[Identity]) -> None:
    """Remove the regular file `parts` below `out` when it has one of `identities`, then the
    folders it leaves empty."""
    with contextlib.suppress(OSError, ValueError):
        for depth in range(len(parts), 0, -1):  # the file, then its folders up to `out`
            folder = _folder(out, parts[: depth - 1])
            try:
                if depth < len(parts):
                    os.rmdir(parts[depth - 1], dir_fd=folder)  # when empty
                    continue
                info = os.stat(parts[-1], dir_fd=folder, follow_symlinks=False)
                if not stat.S_ISREG(info.st_mode) or _identity(info) not in identities:
                    return
                os.unlink(parts[-1], dir_fd=folder)
            finally:
                os.close(folder)


LINK_ERRORS = (errno.ELOOP, errno.ENOTDIR)  # opening a link or a file as a folder, unfollowed


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_NOFOLLOW, 0o644)
    except OSError as exc:
        problem = "a link, not impactlab's lock file" if exc.errno == errno.ELOOP else exc.strerror
        raise OutputError(path, f"cannot write there: {problem or exc}") from None
    with open(fd, "a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
