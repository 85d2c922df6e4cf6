"""How results show to a person: numbers, one-line reprs and small escaped HTML tables."""

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


NOTHING = "\u2013"  # an en dash: no value
TIMES = "\u00d7"
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def number(x: Any, digits: int | None = 3) -> str:
    """A number as a person reads it: `digits` significant digits without an exponent from
    0.001 to 100,000 (0.0185, 28.4, 7.54), else as a power of ten (7.1 x 10^-15, with a times
    sign and superscripts); `digits` None for a parameter as given (0.0005, 3); a dash for
    nothing (None, NaN)."""
    if x is None or isinstance(x, str):
        return x or NOTHING
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return f"{x:,}" if abs(x) >= 10_000 else str(x)
    if not isinstance(x, float):
        return str(x)
    if not math.isfinite(x):
        return NOTHING if math.isnan(x) else ("inf" if x > 0 else "-inf")
    if x == 0:
        return "0"
    if digits is None:  # as given: every digit that is there
        text = f"{x:.12g}"
    elif 1e-3 <= abs(x) < 1e5:
        decimals = max(digits - 1 - math.floor(math.log10(abs(x))), 0)
        return f"{x:.{decimals}f}"
    else:
        text = f"{x:.{max(digits - 1, 0)}e}"
    if "e" not in text:
        return text
    mantissa, exponent = text.split("e")
    return f"{mantissa} {TIMES} 10{str(int(exponent)).translate(_SUPERSCRIPT)}"


def html_table(
    headers: Sequence[str],
    rows: Sequence[Sequence[Any]],
    *,
    caption: str = "",
    total: int | None = None,
    unit: str = "rows",
) -> str:
    """A small HTML table: the first MAX_ROWS rows, then `… and N more <unit>` when `total`
    (or len(rows)) is larger. Every caption, header and cell is escaped; a cell's number reads
    to 4 significant digits."""
    total = len(rows) if total is None else total
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = [
        "<tr>" + "".join(f"<td>{html.escape(plain(number(v, 4)))}</td>" for v in row) + "</tr>"
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
