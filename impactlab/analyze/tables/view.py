"""An analysis result as a notebook shows it: one line (`repr`) or a small HTML table.

The `AnalysisResult` is typed `Any` here: its module imports this one (no import circle).
"""

from __future__ import annotations

from typing import Any

from impactlab.show import count, html_table, where

RUN_COLUMNS = {  # column of the runs table: its header in the HTML table
    "run_id": "run",
    "experiment": "experiment",
    "outcome": "outcome",
    "n_bounces": "bounces",
    "e_velocity_mean": "e (mean)",
    "n_collisions": "collisions",
    "e_collision": "e (collision)",
    "energy_loss_frac": "energy lost (fraction)",
}


def analysis_repr(result: Any) -> str:
    """`<Analysis 17 runs, 42 bounces, 3 collisions, results/>` (failed inputs counted)."""
    parts = [
        count(result.runs.height, "run"),
        count(_total(result, "n_bounces"), "bounce"),
        count(_total(result, "n_collisions"), "collision"),
    ]
    if result.failed:
        parts.append(f"{len(result.failed):,} failed")
    parts.append(where(result.out_dir) if result.out_dir is not None else "nothing written")
    return f"<Analysis {', '.join(parts)}>"


def _total(result: Any, column: str) -> int:
    """The runs table's count summed over the runs (a run without bounces has a row in the
    bounces table that says why, so the table's height is not the count)."""
    if column not in result.runs.columns:
        return 0
    return int(result.runs[column].sum() or 0)


def analysis_html(result: Any) -> str:
    """One row per run (its bounces, e, collisions, energy lost), then the failed inputs."""
    runs = result.runs
    columns = [c for c in RUN_COLUMNS if c in runs.columns]
    rows = runs.head(30).select(columns).rows() if columns else []
    caption = analysis_repr(result).strip("<>")
    table = html_table(
        [RUN_COLUMNS[c] for c in columns], rows, caption=caption, total=runs.height, unit="runs"
    )
    if result.failed:
        failed = [[path, why] for path, why in result.failed]
        table += html_table(["failed input", "why"], failed, unit="inputs")
    return table
