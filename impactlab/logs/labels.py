"""A run's sweep point in words and units, one scheme for every stage that labels runs.

The report's tables and figures (`impactlab.analyze.tables.labels`, `run_figures`) and the replay's
series names (`impactlab.replay.recordings`) all read "ball released at z = 3 m", never a
hash or the spec's dotted keys.
"""

from __future__ import annotations

import re

_AXES = "xyz"
_UNITS = {"pos": "m", "vel": "m/s", "mass": "kg", "radius": "m", "size": "m"}


def parameter_words(key: str, value: object) -> str:
    """One sweep parameter in words and units, e.g. `ball.pos[2]` = 3 -> "ball at z = 3 m"."""
    shown = f"{value:g}" if isinstance(value, float) else str(value)
    match = re.fullmatch(r"(?:bodies\.)?(\w+)\.(pos|vel)\[(\d)\]", key)
    if match:
        body, what, axis = match.groups()
        if what == "pos":
            return f"{body} released at {_AXES[int(axis)]} = {shown} m"
        return f"{body} v{_AXES[int(axis)]} = {shown} m/s"
    match = re.fullmatch(r"(?:bodies\.)?(\w+)\.(mass|radius)", key)
    if match:
        body, what = match.groups()
        return f"{body} {what} = {shown} {_UNITS[what]}"
    if key.startswith("contact."):
        return f"{key.removeprefix('contact.')} = {shown}"
    return f"{key} = {shown}"


def sweep_words(sweep: dict[str, object]) -> str:
    """A run's sweep point in words and units ("ball released at z = 3 m"); "" for none.

    A swept vector shows its non-zero components (all of them when every one is zero).
    """
    words = []
    for key, value in sweep.items():
        if isinstance(value, list | tuple):
            shown = [i for i, x in enumerate(value) if x] or list(range(len(value)))
            words += [parameter_words(f"{key}[{i}]", value[i]) for i in shown]
        else:
            words.append(parameter_words(key, value))
    return ", ".join(words)
