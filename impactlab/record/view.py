"""A record job's result as a notebook shows it: one line (`repr`) or a small HTML table."""

from __future__ import annotations

from typing import Any

from impactlab.show import count, html_table, where

# a `RecordResult` is typed `Any` here: its module imports this one (no import circle)


def record_repr(result: Any) -> str:
    """`<RecordResult 3 runs: 2 recorded, 1 reused, logs/>` (unstable and failed counted)."""
    parts = [
        f"{len(getattr(result, kind)):,} {kind}"
        for kind in ("recorded", "reused", "unstable", "failed")
        if getattr(result, kind)
    ]
    folders = {r.path.parent for r in result}
    head = count(len(result), "run") + (f": {', '.join(parts)}" if parts else "")
    folder = f", {where(next(iter(folders))) if len(folders) == 1 else 'several folders'}"
    return f"<RecordResult {head}{folder if folders else ''}>"


def record_html(result: Any) -> str:
    """One row per run: its status, outcome and why, simulated time, steps, log file."""
    rows = [
        [r.run_id, r.status, r.outcome, r.reason, r.t_end_s or None, r.steps or None, r.path.name]
        for r in result[:30]
    ]
    headers = ["run", "status", "outcome", "why", "t end (s)", "steps", "log"]
    caption = record_repr(result).strip("<>")
    return html_table(headers, rows, caption=caption, total=len(result), unit="runs")
