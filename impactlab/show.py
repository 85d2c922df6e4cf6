"""How results show in a notebook or a console: one-line reprs and small HTML tables.

Every text that comes from a log, a model or a spec (run ids, body names, paths) is
untrusted: `plain` turns control characters into visible escapes (no terminal escape gets
through a repr), and `html_table` escapes every cell and caption with `html.escape` (no
markup gets through a notebook's HTML output).
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

MAX_ROWS = 20
"""Rows an HTML table shows; the rest are counted in its last row."""


def plain(text: Any) -> str:
    """`text` as one printable line: control and other unprintable characters escaped."""
    s = str(text)
    if s.isprintable():
        return s
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in s)


def where(path: Path | str | None) -> str:
    """A folder as the repr names it (`results/`), or a file (`x.mcap`); "" for None."""
    if path is None:
        return ""
    p = Path(path)
    return plain(f"{p}/" if p.suffix == "" else str(p))


def cell(value: Any) -> str:
    """A table cell's text: numbers to 4 significant digits, nothing for None or NaN."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.4g}"
    if isinstance(value, int):
        return f"{value:,}"
    return plain(value)


def html_table(
    headers: Sequence[str],
    rows: Sequence[Sequence[Any]],
    *,
    caption: str = "",
    total: int | None = None,
    unit: str = "rows",
) -> str:
    """A small HTML table: the first MAX_ROWS rows, then `… and N more <unit>` when `total`
    (or len(rows)) is larger. Every caption, header and cell is escaped."""
    total = len(rows) if total is None else total
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = [
        "<tr>" + "".join(f"<td>{html.escape(cell(v))}</td>" for v in row) + "</tr>"
        for row in rows[:MAX_ROWS]
    ]
    shown = min(len(rows), MAX_ROWS)
    if total > shown:
        more = html.escape(f"… and {total - shown:,} more {unit}")
        body.append(f'<tr><td colspan="{len(headers)}">{more}</td></tr>')
    cap = f"<caption>{html.escape(caption)}</caption>" if caption else ""
    return (
        f'<table class="impactlab">{cap}<thead><tr>{head}</tr></thead>'
        f"<tbody>{''.join(body)}</tbody></table>"
    )


def count(n: int, noun: str, plural: str = "") -> str:
    """`1 run`, `17 runs` (`plural` where it is not noun + s)."""
    return f"{n:,} {noun if n == 1 else plural or noun + 's'}"
