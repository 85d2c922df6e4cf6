"""MuJoCo's warnings kept in memory: never `MUJOCO_LOG.TXT` in the working folder.

By default MuJoCo prints a warning and appends it to `MUJOCO_LOG.TXT` in the working folder.
`quiet_mujoco` installs a handler (`mujoco.set_mju_user_warning`, once per process) that
keeps the last messages in `MESSAGES` instead; `parse_warnings` gives those a parse raised
(MuJoCo's parser warns, e.g., of a NaN in the model).
"""

from __future__ import annotations

import collections
import threading
from collections.abc import Callable
from typing import TypeVar

MESSAGES: collections.deque[str] = collections.deque(maxlen=100)  # the last ones, any run
_installed = threading.Lock()
_done = False
T = TypeVar("T")


def _keep(message: str) -> None:
    MESSAGES.append(" ".join(str(message).split()))


def quiet_mujoco() -> None:
    """Route MuJoCo's warnings to `MESSAGES` (once per process; no MUJOCO_LOG.TXT)."""
    import mujoco

    global _done
    with _installed:
        if not _done:
            mujoco.set_mju_user_warning(_keep)
            _done = True


def parse_warnings(parse: Callable[[], T]) -> tuple[T, list[str]]:
    """Call `parse` (e.g. `mujoco.MjSpec.from_file`) with MuJoCo's warnings kept from the
    working folder; its result and the warnings it raised."""
    quiet_mujoco()
    marker = f"impactlab: parse {id(parse)} {threading.get_ident()}"
    MESSAGES.append(marker)
    try:
        result = parse()
    finally:
        kept = list(MESSAGES)
        fresh = kept[kept.index(marker) + 1 :] if marker in kept else kept
        if marker in kept:
            MESSAGES.remove(marker)
    return result, fresh


def nan_warning(messages: list[str]) -> str | None:
    """MuJoCo's parser warning of a NaN among `messages`, if any."""
    return next((m for m in messages if "NaN" in m), None)
