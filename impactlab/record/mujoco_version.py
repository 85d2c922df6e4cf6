"""The MuJoCo versions impactlab records with: 3.3 and newer (pyproject: mujoco>=3.3,<4.1).

Measured: 3.3.7 and 4.0.0 give every bounce's e to the printed digit (CI runs the restitution
tests on both, `.ci/run`); 3.2 lacks the energy sensors the recorder adds, 3.0 the `MjSpec`
models are built with. Importing this module (as `record.model` does) checks the installed
MuJoCo, so an older one installed by hand (`pip install --no-deps`) is one error line.
"""

from __future__ import annotations

import mujoco

from impactlab.errors import ImpactlabError

MINIMUM = (3, 3)


def version_tuple(version: str) -> tuple[int, ...]:
    """(3, 3, 7) for "3.3.7"; a suffix such as "rc1" or ".dev0" ends the numbers."""
    numbers = []
    for part in version.split("."):
        digits = _leading_digits(part)
        if not digits:
            break
        numbers.append(int(digits))
        if len(digits) < len(part):
            break
    return tuple(numbers)


def _leading_digits(part: str) -> str:
    """The leading digits of `part`."""
    end = 0
    while end < len(part) and part[end].isdigit():
        end += 1
    return part[:end]


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
