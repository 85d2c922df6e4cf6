"""A decoded log as a notebook shows it: one line (`repr`) or a small HTML table.

The `RunLog` is typed `Any` here: its module imports this one (no import circle).
"""

from __future__ import annotations

from typing import Any

from impactlab.show import count, html_table, plain


def _duration_s(log: Any) -> float | None:
    ends = [float(f["t_s"][-1]) for f in log.bodies.values() if f.height]
    return max(ends) if ends else None


def log_repr(log: Any) -> str:
    """`<RunLog drop-1: drop, completed, 1.39 s, 1 body, 13,903 states, 26 contact points>`."""
    parts = [plain(log.experiment) or "unknown experiment", plain(log.outcome)]
    duration = _duration_s(log)
    if duration is not None:
        parts.append(f"{duration:.4g} s")
    states = sum(f.height for f in log.bodies.values())
    parts += [
        count(len(log.bodies), "body", "bodies"),
        count(states, "state"),
        count(log.contacts.height, "contact point"),
    ]
    if log.partial:
        parts.append(f"partial: {count(len(log.problems), 'problem')}")
    return f"<RunLog {plain(log.run_id)}: {', '.join(parts)}>"


def log_html(log: Any) -> str:
    """The run, its outcome, and one row per channel with its rows and time span."""
    rows: list[list[object]] = []
    for name, frame in log.bodies.items():
        t = frame["t_s"]
        rows.append([f"body {name}", frame.height, t.min(), t.max()])
    for label, frame in (("contact points", log.contacts), ("energy", log.energy)):
        t = frame["t_s"] if frame.height else None
        rows.append(
            [label, frame.height, None if t is None else t.min(), None if t is None else t.max()]
        )
    rows.append(["events", log.events.height, None, None])
    reason = log.meta.get("reason", "")
    caption = f"{log.run_id} ({log.experiment or 'unknown experiment'}): {log.outcome}"
    caption += f" ({reason})" if reason else ""
    caption += f"; {log.path}"
    table = html_table(["channel", "rows", "first t (s)", "last t (s)"], rows, caption=caption)
    if log.problems:
        problems = [[p] for p in log.problems]
        table += html_table(["problems (partial log)"], problems, unit="problems")
    return table
