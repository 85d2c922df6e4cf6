"""The HTML writer: a document's blocks as one self-contained page, every text escaped here.

Figures are embedded as data URIs (the page can be mailed or moved alone), and only figure
files inside the page's folder; its Content Security Policy allows no script and no request.
"""

from __future__ import annotations

import base64
import os
import stat
from html import escape as _escape
from pathlib import Path
from urllib.parse import quote

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
from impactlab.text import visible

CSP = (
    "default-src 'none'; img-src data:; style-src 'unsafe-inline'; base-uri 'none'; "
    "form-action 'none'"
)
"""No script, nothing loaded but the page's own inline figures and style."""
MAX_FIGURE_BYTES = 64 * 2**20
"""The largest figure file embedded."""
CONTENTS_END = "<!-- end of contents -->"
PAGE_END = "</main>\n</body>\n</html>\n"

STYLE = """
body { font-family: system-ui, sans-serif; max-width: 52rem; margin: 2rem auto;
       padding: 0 1rem; line-height: 1.45; color: #1b1b1b; }
h1, h2, h3 { line-height: 1.2; }
table { border-collapse: collapse; margin: 0.6rem 0; font-size: 0.85rem; }
th, td { border: 1px solid #ccc; padding: 0.2rem 0.4rem; text-align: left; vertical-align: top; }
th { background: #f3f3f3; }
td.n { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
figure { margin: 0.8rem 0; }
figure img { max-width: 100%; max-height: 32rem; height: auto; display: block; }
figcaption, p.more, ol.notes { font-size: 0.8rem; color: #444; }
ol.notes { margin-top: 0.2rem; }
nav ul { columns: 2; }
@page { size: A4; margin: 14mm 14mm 16mm; }
@media print {
  body { max-width: none; margin: 0; padding: 0; font-size: 10pt; }
  table { font-size: 7.5pt; page-break-inside: auto; }
  td { overflow-wrap: anywhere; }
  td, th { padding: 0.1rem 0.25rem; }
  tr, figure, img { page-break-inside: avoid; break-inside: avoid; }
  h2, h3 { page-break-after: avoid; break-after: avoid; }
  figure img { max-height: 95mm; width: auto; max-width: 100%; }
  a { color: inherit; text-decoration: none; }
}
"""


def escape(text: str) -> str:
    """Text as HTML that shows exactly it: markup escaped, control characters as escapes."""
    return _escape(visible(text))


def html(doc: Document, folder: Path) -> str:
    """The document as one page; figure files are read from inside `folder` only."""
    body = "".join(block_html(b, folder, doc.blocks) for b in doc.blocks)
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f'<meta http-equiv="Content-Security-Policy" content="{CSP}">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{escape(doc.title)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<main>\n"
        f"<h1>{escape(doc.title)}</h1>\n{body}{PAGE_END}"
    )


def block_html(block: Block, folder: Path, blocks: list[Block]) -> str:
    """One block as HTML (`blocks`: the document's, for its contents)."""
    if isinstance(block, Heading):
        n = block.level
        return f'<h{n} id="{escape(block.anchor)}">{escape(block.text)}</h{n}>\n'
    if isinstance(block, Paragraph):
        return f"<p>{spans(block.spans)}</p>\n"
    if isinstance(block, Bullets):
        return "<ul>\n" + "".join(f"<li>{spans(i)}</li>\n" for i in block.items) + "</ul>\n"
    if isinstance(block, Table):
        return table(block)
    if isinstance(block, Figure):
        return figure(block, folder)
    if isinstance(block, Contents):
        items = contents([b for b in blocks if isinstance(b, Heading)])
        return f"<nav>\n<ul>\n{items}{CONTENTS_END}\n</ul>\n</nav>\n"
    raise TypeError(f"not a block: {block!r}")


def contents(headings: list[Heading]) -> str:
    return "".join(
        f'<li><a href="#{escape(quote(h.anchor))}">{escape(h.text)}</a></li>\n'
        for h in headings
        if h.level == 2
    )


def spans(items: tuple[Span, ...]) -> str:
    out = []
    for s in items:
        if isinstance(s, Link):
            path, _, anchor = s.target.partition("#")
            href = quote(path) + (f"#{quote(anchor)}" if anchor else "")
            out.append(f'<a href="{escape(href)}">{escape(s.text)}</a>')
        elif isinstance(s, str):
            out.append(escape(s))
        else:
            out.append(f"<strong>{escape(s.text)}</strong>")
    return "".join(out)


def table(t: Table) -> str:
    rows, more = rows_shown(t)
    out = ["<table>\n<thead><tr>"]
    out += [f"<th>{escape(c.title)}</th>" for c in t.columns]
    out.append("</tr></thead>\n<tbody>\n")
    numeric = [rows.schema[c.name].is_numeric() for c in t.columns]
    for row in rows.select(c.name for c in t.columns).iter_rows():
        out.append("<tr>")
        for value, column, n in zip(row, t.columns, numeric, strict=True):
            out.append(f"<td{' class=n' if n else ''}>{escape(cell(value, column))}</td>")
        out.append("</tr>\n")
    out.append("</tbody>\n</table>\n")
    if more:
        out.append(f'<p class="more">{spans(more)}</p>\n')
    if t.notes:
        notes = "".join(f"<li>{escape(n)}</li>" for n in t.notes)
        out.append(f'<ol class="notes">{notes}</ol>\n')
    return "".join(out)


def figure(f: Figure, folder: Path) -> str:
    caption = f"<figcaption>{escape(f.caption)}</figcaption>"
    data = figure_bytes(f.path, folder)
    if isinstance(data, str):
        return f"<figure><p>Figure not shown ({escape(data)}).</p>{caption}</figure>\n"
    uri = "data:image/png;base64," + base64.b64encode(data).decode()
    return f'<figure><img src="{uri}" alt="{escape(f.caption)}">{caption}</figure>\n'


def figure_bytes(path: Path, folder: Path) -> bytes | str:
    """The PNG at `path`, or why it is not embedded: only a regular .png file inside `folder`
    (links resolved) of at most `MAX_FIGURE_BYTES` is read."""
    root = folder.resolve()
    file = (folder / path).resolve()
    if not file.is_relative_to(root) or file.suffix.lower() != ".png":
        return "not a figure file in the report's folder"
    try:
        with open(file, "rb", opener=_no_block) as stream:
            info = os.fstat(stream.fileno())
            if not stat.S_ISREG(info.st_mode):
                return "not a regular file"
            data = stream.read(MAX_FIGURE_BYTES + 1)
    except OSError:
        return "missing"
    if len(data) > MAX_FIGURE_BYTES:
        return f"over {MAX_FIGURE_BYTES >> 20} MiB"
    return data


def _no_block(path: str, flags: int) -> int:
    """Open without waiting (a pipe named like a figure would wait for a writer)."""
    return os.open(path, flags | os.O_NONBLOCK)
