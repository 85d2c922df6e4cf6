"""The report as a list of blocks, and how their numbers read (`impactlab.show.number`)."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import polars as pl

from impactlab.show import NOTHING, number


@dataclass(frozen=True)
class Link:
    """A link: `target` a relative file, "#anchor" or "file#anchor" (made by the report, never
    from a name)."""

    text: str
    target: str


@dataclass(frozen=True)
class Strong:
    """Text set in bold."""

    text: str


Span = str | Link | Strong
"""A piece of a paragraph: plain text (escaped by the writer), a link or bold text."""


@dataclass(frozen=True)
class Heading:
    """A section heading of `level` 1..3; its anchor is `slug(text)`."""

    text: str
    level: int = 2

    @property
    def anchor(self) -> str:
        return slug(self.text)


@dataclass(frozen=True)
class Paragraph:
    spans: tuple[Span, ...]


@dataclass(frozen=True)
class Bullets:
    items: tuple[tuple[Span, ...], ...]


@dataclass(frozen=True)
class Column:
    """A table column: the frame's column `name`, its header and unit, and how its numbers
    read (`digits` significant, or None: as given, for parameters)."""

    name: str
    header: str
    unit: str = ""
    digits: int | None = 3

    @property
    def title(self) -> str:
        return f"{self.header} ({self.unit})" if self.unit else self.header


@dataclass(frozen=True)
class Table:
    """A table of `frame`'s `columns`, at most `limit` rows (None: `REPORT_ROWS`); `notes`:
    the footnotes its cells point to (`footnoted`); `source`: where every row is."""

    frame: pl.DataFrame
    columns: tuple[Column, ...]
    notes: tuple[str, ...] = ()
    source: Span = ""
    limit: int | None = None


@dataclass(frozen=True)
class Figure:
    path: Path
    caption: str


@dataclass(frozen=True)
class Contents:
    """A list of links to the document's sections (its level-2 headings)."""


Block = Heading | Paragraph | Bullets | Table | Figure | Contents


@dataclass
class Document:
    """A file of the report: its title and blocks (written by `markdown` and `html`)."""

    title: str
    blocks: list[Block] = field(default_factory=list)


REPORT_ROWS = 500
"""Rows a table shows; beyond them it says how many more its source file holds, so the report
of a sweep of 100,000 runs stays one a person can read, in bounded memory."""


def rows_shown(table: Table) -> tuple[pl.DataFrame, tuple[Span, ...]]:
    """The rows of `table` written, and the sentence on those left out (none: empty)."""
    n, limit = table.frame.height, REPORT_ROWS if table.limit is None else table.limit
    if n <= limit:
        return table.frame, ()
    more = f"The first {limit:,} of {n:,} rows"
    where = ("; all of them are in ", table.source, ".") if table.source else (".",)
    return table.frame.head(limit), (more, *where)


def footnoted(frame: pl.DataFrame, column: str) -> tuple[pl.DataFrame, tuple[str, ...]]:
    """The frame with its text column `column` replaced by footnote marks ("1", "2", ...: the
    same text, the same mark), and the notes in order; empty texts get no mark."""
    if column not in frame.columns:
        return frame, ()
    texts = frame[column].head(REPORT_ROWS).to_list()
    notes = list(dict.fromkeys(t for t in texts if t))
    marks = [str(notes.index(t) + 1) if t else "" for t in texts]
    marks += [""] * (frame.height - len(marks))
    return frame.with_columns(pl.Series(column, marks, dtype=pl.String)), tuple(notes)


def slug(text: str) -> str:
    """A heading's anchor as GitHub makes it (lower case, punctuation dropped, spaces as -)."""
    return re.sub(r"[^\w\- ]", "", text.lower()).replace(" ", "-")


def quantity(x: Any, unit: str, digits: int | None = 3) -> str:
    """`number(x, digits)` with its unit."""
    return f"{number(x, digits)} {unit}" if unit else number(x, digits)


def percent(fraction: Any, digits: int = 3) -> str:
    """A fraction as a percentage (0.832 -> "83.2 %")."""
    return NOTHING if fraction is None else f"{number(fraction * 100, digits)} %"


def span(values: Sequence[Any], unit: str = "", digits: int | None = 3) -> str:
    """The range of the defined values ("0.799 to 0.801", one value alone); "" for none."""
    xs = [v for v in values if isinstance(v, int | float) and math.isfinite(v)]
    if not xs:
        return ""
    lo, hi = number(min(xs), digits), number(max(xs), digits)
    tail = f" {unit}" if unit else ""
    return f"{lo}{tail}" if lo == hi else f"{lo} to {hi}{tail}"


def cell(value: Any, column: Column) -> str:
    """A table cell's text (escaped by the writer)."""
    return value if isinstance(value, str) else number(value, column.digits)
