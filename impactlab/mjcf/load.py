"""An MJCF model parsed and compiled by MuJoCo, its warnings kept out of the working folder."""

from __future__ import annotations

import collections
import contextlib
import functools
import threading
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from impactlab.errors import SpecError
from impactlab.mjcf.files import included_files

if TYPE_CHECKING:
    import mujoco  # imported where used: `impactlab.mjcf` loads without it

MESSAGES: collections.deque[str] = collections.deque(maxlen=100)  # the last ones, any run
T = TypeVar("T")


def _keep(message: str) -> None:
    MESSAGES.append(" ".join(str(message).split()))


@functools.cache
def quiet_mujoco() -> None:
    """Route MuJoCo's warnings to `MESSAGES` (once per process; no MUJOCO_LOG.TXT)."""
    import mujoco

    mujoco.set_mju_user_warning(_keep)


def one_line(exc: BaseException) -> str:
    """An exception's message on one line (MuJoCo's parser messages span several)."""
    return " ".join(str(exc).split())


def parse_mjcf(path: Path) -> mujoco.MjSpec:
    """Parse an MJCF file with MuJoCo (its includes and assets as MuJoCo resolves them), its
    warnings kept from the working folder; every file it names must be a regular file.

    Raises:
        SpecError: the file is missing, MuJoCo cannot parse it, it holds a NaN, or a file it
            names is not a regular file (a FIFO, a device).
    """
    import mujoco

    spec: mujoco.MjSpec = _read(path, lambda: mujoco.MjSpec.from_file(str(path)))
    return spec


def load_model(path: Path) -> mujoco.MjModel:
    """Compile an MJCF file of any name as `parse_mjcf` parses it, its names checked.

    Raises:
        SpecError: as `parse_mjcf`; MuJoCo cannot compile it; a name is not UTF-8 text.
    """
    import mujoco

    model: mujoco.MjModel = _read(path, lambda: mujoco.MjModel.from_xml_path(str(path)))
    check_names(model, str(path))
    return model


def _read(path: Path, parse: Callable[[], T]) -> T:
    """`parse` (MuJoCo reading `path`) once its files are checked, warnings kept; a NaN it
    warns of is an error."""
    import mujoco

    if not path.is_file():
        raise SpecError(str(path), "", "not a regular file" if path.exists() else "file not found")
    for file in included_files(path):
        if file.exists() and not file.is_file():  # MuJoCo would read a FIFO forever
            raise SpecError(str(path), "", f"{file} is not a regular file")
    # MuJoCo caches compiled meshes and textures by file name: a file edited since would be
    # read from the cache, stale, so every user model is read from its files again
    mujoco.mj_clearCache(mujoco.mj_getCache())
    quiet_mujoco()
    marker = f"impactlab: parse {id(parse)} {threading.get_ident()}"  # where its warnings start
    MESSAGES.append(marker)
    try:
        result = parse()
    except Exception as exc:  # MuJoCo raises ValueError with the parser's message
        raise SpecError(str(path), "", f"invalid MJCF: {one_line(exc)}") from None
    finally:
        kept = list(MESSAGES)
        fresh = kept[kept.index(marker) + 1 :] if marker in kept else kept
        if marker in kept:
            MESSAGES.remove(marker)
    nan = next((m for m in fresh if "NaN" in m), None)
    if nan is not None:
        raise SpecError(str(path), "", f"invalid MJCF: a number is NaN ({nan})")
    return result


@contextlib.contextmanager
def kept_warnings() -> Iterator[None]:
    """MuJoCo's Python warnings (MjSpec's compile, to_xml: a deprecated attribute, a singular
    inertia) kept in `MESSAGES` instead of printed with a source line of impactlab's."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    for warning in caught:
        _keep(str(warning.message))


def compile_spec(spec: mujoco.MjSpec, source: str) -> mujoco.MjModel:
    """Compile a parsed model, its warnings kept (`kept_warnings`).

    Raises:
        SpecError: MuJoCo cannot compile it.
    """
    with kept_warnings():
        try:
            model: mujoco.MjModel = spec.compile()
        except Exception as exc:
            raise SpecError(source, "", f"invalid MJCF: {one_line(exc)}") from None
    return model


def check_names(model: mujoco.MjModel, source: str) -> None:
    """MuJoCo keeps names as the file's bytes; Python reads them as UTF-8.

    Raises:
        SpecError: a name is not UTF-8 (e.g. an ISO-8859-1 model with an accent).
    """
    try:
        bytes(model.names).decode("utf-8")
    except UnicodeDecodeError as exc:
        raw = bytes(model.names)
        start = raw.rfind(b"\0", 0, exc.start) + 1
        stop = raw.find(b"\0", exc.start)
        name = raw[start : stop if stop >= 0 else None].decode("utf-8", "backslashreplace")
        raise SpecError(
            source,
            "",
            f"the name {name!r} is not UTF-8 text (MuJoCo reads names as UTF-8 bytes): "
            "save the model as UTF-8",
        ) from None
