"""The MuJoCo versions impactlab records with, checked on import: 3.3 and newer."""

from __future__ import annotations

import re

import mujoco

from impactlab.errors import ImpactlabError

MINIMUM = (3, 3)  # why: docs/layout.md


def version_tuple(version: str) -> tuple[int, ...]:
    """(3, 3, 7) for "3.3.7"; a suffix such as "rc1" or ".dev0" ends the numbers."""
    numbers = re.match(r"\d+(\.\d+)*", version)
    return tuple(int(n) for n in numbers.group().split(".")) if numbers else ()


def require_mujoco(version: str) -> None:
    """Raise unless `version` is at least `MINIMUM`.

    Raises:
        ImpactlabError: the installed MuJoCo is too old (the message says which and why).
    """
    if version_tuple(version) < MINIMUM:
        raise ImpactlabError(
            f"MuJoCo {version} is installed; impactlab needs 3.3 or newer (its energy sensors "
            "and MjSpec): pip install 'mujoco>=3.3,<4.1'"
        )


require_mujoco(mujoco.__version__)
