"""The Markdown writer: a document's blocks as Markdown, every text escaped here (`md_text`)."""

from __future__ import annotations

import os
from pathlib import Path

from impactlab.analyze.report.blocks import (
    Block,
    Bullets,
    Contents,
    Document,
    Figure,
    Heading,
    Link,
    Paragraph,
    Span,
    Table,
    cell,
    rows_shown,
)
from impactlab.text import md_link, md_text

CONTENTS_END = "<!-- end of contents -->"
"""Ends the list of sections, so that sections added later (`append`) are listed too."""


def markdown(doc: Document, folder: Path) -> str:
    """The document as Markdown; figure paths relative to `folder` (the file's)."""
    parts = [f"# {md_text(doc.title)}\n"]
    parts += [block_markdown(b, folder, doc.blocks) for b in doc.blocks]
    return "\n".join(parts)


def block_markdown(block: Block, folder: Path, blocks: list[Block]) -> str:
    """One block as Markdown (`blocks`: the document's, for its contents)."""
    if isinstance(block, Heading):
        return f"{'#' * block.level} {md_text(block.text)}\n"
    if isinstance(block, Paragraph):
        return spans(block.spans) + "\n"
    if isinstance(block, Bullets):
        return "".join(f"- {spans(item)}\n" for item in block.items)
    if isinstance(block, Table):
        return table(block)
    if isinstance(block, Figure):
        target = md_link(os.path.relpath(block.path, folder))
        caption = md_text(block.caption, line_start=False)
        return f"![{caption}]({target})\n\n*{caption}*\n"
    if isinstance(block, Contents):
        return contents([b for b in blocks if isinstance(b, Heading)]) + CONTENTS_END + "\n"
    raise TypeError(f"not a block: {block!r}")


def contents(headings: list[Heading]) -> str:
    """The list items linking the level-2 headings."""
    return "".join(
        f"- [{md_text(h.text, line_start=False)}](#{md_link(h.anchor)})\n"
        for h in headings
        if h.level == 2
    )


def spans(items: tuple[Span, ...], *, line_start: bool = True) -> str:
    """A paragraph's text: only its start can begin a block (a heading, a list item)."""
    out: list[str] = []
    for s in items:
        start = line_start and not out
        if isinstance(s, Link):
            path, _, anchor = s.target.partition("#")
            target = md_link(path) + (f"#{md_link(anchor)}" if anchor else "")
            if out and out[-1].endswith("!"):  # "![" would make the link an image
                out[-1] = out[-1][:-1] + "\\!"
            out.append(f"[{md_text(s.text, line_start=False)}]({target})")
        elif isinstance(s, str):
            out.append(md_text(s, line_start=start))
        else:
            out.append(f"**{md_text(s.text, line_start=False)}**")
    return "".join(out)


def table(t: Table) -> str:
    rows, more = rows_shown(t)
    lines = [
        "| " + " | ".join(md_text(c.title, line_start=False) for c in t.columns) + " |",
        "|" + "---|" * len(t.columns),
    ]
    for row in rows.select(c.name for c in t.columns).iter_rows():
        cells = (md_text(cell(v, c), line_start=False) for v, c in zip(row, t.columns, strict=True))
        lines.append("| " + " | ".join(cells) + " |")
    out = "\n".join(lines) + "\n"
    if more:
        out += f"\n*{spans(more, line_start=False)}*\n"
    if t.notes:
        out += "\n" + "".join(f"{i}. {md_text(n)}\n" for i, n in enumerate(t.notes, 1))
    return out
