"""The report as one self-contained HTML page: report.md rendered, its figures embedded.

The page is what gets handed in or opened in a browser: every figure the Markdown shows is
inlined as a data URI (so the page can be mailed or moved alone), headings get the ids that
GitHub gives them (so the report's in-page links work in both), and links to other files
(tables, replays, the calibration details) stay relative, working beside the results.

Nothing a model or a log says can run or load in the page: raw HTML in the Markdown is shown
as text, only figure files inside the report's folder are embedded (any other image becomes
its alt text), and the page's Content Security Policy allows no script and no request.
"""

from __future__ import annotations

import base64
import html
import re
import shutil
import stat
from array import array
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, overload
from urllib.parse import unquote, urlsplit

from markdown_it import MarkdownIt
from markdown_it.common.utils import escapeHtml
from markdown_it.rules_core import StateCore
from markdown_it.token import Token
from mdit_py_plugins.anchors.index import slugify, unique_slug

from impactlab.files import atomic_path, temporary_path

STYLE = """
body { font-family: system-ui, sans-serif; max-width: 60rem; margin: 2rem auto;
       padding: 0 1rem; line-height: 1.5; color: #1b1b1b; }
h1, h2, h3 { line-height: 1.25; }
table { border-collapse: collapse; margin: 1rem 0; font-size: 0.9rem; display: block;
        overflow-x: auto; }
th, td { border: 1px solid #ccc; padding: 0.25rem 0.5rem; text-align: left; }
th { background: #f3f3f3; }
img { max-width: 100%; height: auto; display: block; margin: 0.5rem 0; }
code { background: #f3f3f3; padding: 0 0.2rem; }
pre { background: #f3f3f3; padding: 0.5rem; overflow-x: auto; }
"""


CSP = (
    "default-src 'none'; img-src data:; style-src 'unsafe-inline'; base-uri 'none'; "
    "form-action 'none'"
)
"""The page's Content Security Policy: no script, nothing loaded but its own inline figures
and style."""
FIGURE_TYPES = {".png": "image/png", ".jpg": "image/jpeg", ".jpeg": "image/jpeg"}
"""The images the page embeds, by file suffix (the analysis draws PNG)."""
MAX_FIGURE_BYTES = 64 * 2**20
"""The largest figure file embedded."""

SLICE_ROWS = 200
"""A table of more rows is parsed in slices of this many rows (the page is the same)."""
_FENCE = re.compile(r" {0,3}(`{3,}|~{3,})")
_HEADING = re.compile(r"#{1,6}(\s|$)")  # at the margin: never inside a list or a quote
_TITLE = re.compile(r"^# [^\n]*", re.MULTILINE)  # the page's title: the first "# " line
_DELIMITER = re.compile(r"\|?\s*:?-+:?\s*(\|\s*:?-+:?\s*)*\|?\s*$")
_HEAD, _TAIL = "<tbody>\n", "</tbody>\n</table>\n"


def _parser() -> MarkdownIt:
    md = MarkdownIt("commonmark", {"html": False}).enable("table")  # raw HTML stays text
    md.core.ruler.push("anchor", _anchors)
    return md


def _anchors(state: StateCore) -> None:
    """GitHub's heading ids (`mdit_py_plugins.anchors`), unique over every piece of one page
    (the ids taken so far are kept in the parse's env)."""
    slugs: set[str] = state.env.setdefault("slugs", set())
    for i, token in enumerate(state.tokens):
        if token.type != "heading_open" or token.attrGet("id"):
            continue
        children = state.tokens[i + 1].children or []
        title = "".join(c.content for c in children if c.type in ("text", "code_inline"))
        token.attrSet("id", unique_slug(slugify(title), slugs))


def _pieces(markdown: str, *, tables: bool = False) -> Iterator[tuple[str, str]]:
    """The Markdown in pieces that render alone as within the whole page: its sections (cut
    before each heading outside a code fence) and, of a table of more than SLICE_ROWS rows
    standing between blank lines, slices of rows under its header. Yields (part, text):
    part "" for Markdown as it is, "first", "middle" or "last" for a table's slices; with
    `tables`, "table" for a smaller table between blank lines (so that a plain one is
    written without markdown-it, `_plain_table`).
    The lines are read from the text as they are needed (`_Lines`), never listed."""
    if _DEFINITION.search(markdown):  # a reference may be defined in another piece: whole
        yield "", markdown
        return
    lines = _Lines(markdown)
    text: list[str] = []
    fence = ""
    i = 0
    while i < len(lines):
        line = lines[i]
        opened = _FENCE.match(line)
        if fence:
            fence = "" if _closes(line, fence) else fence
        elif opened:
            fence = opened.group(1)
        elif _HEADING.match(line) and text:
            yield "", "".join(text)
            text = []
        elif _table_at(lines, i) and (not text or not text[-1].strip()):
            end = i + 2
            while end < len(lines) and lines[end].startswith("|"):
                end += 1
            rows = end - i - 2
            alone = end == len(lines) or not lines[end].strip()
            if tables and alone and rows <= SLICE_ROWS:
                if text:
                    yield "", "".join(text)
                    text = []
                yield "table", "".join(lines[i:end])
                i = end
                continue
            if rows > SLICE_ROWS and alone:
                if text:
                    yield "", "".join(text)
                    text = []
                head = "".join(lines[i : i + 2])
                for at in range(i + 2, end, SLICE_ROWS):
                    part = (
                        "first" if at == i + 2 else "last" if at + SLICE_ROWS >= end else "middle"
                    )
                    yield part, head + "".join(lines[at : min(at + SLICE_ROWS, end)])
                i = end
                continue
        text.append(line)
        i += 1
    if text:
        yield "", "".join(text)


_SYNTAX = re.compile(r"[\\`*<>&]|\]\(|(?<![0-9A-Za-z])_|_(?![0-9A-Za-z])")
"""Anything in a cell that inline Markdown could read as more than text (an underscore only
between two letters or digits cannot open or close emphasis; brackets without a link
destination are text in a page without reference definitions, see `_pieces`)."""
_ESCAPED = re.compile(r"\\([!-/:-@\[-`{-~])")
"""A backslash escape of ASCII punctuation: the punctuation as text (CommonMark)."""
_PIPE = re.compile(r"(?<!\\)\|")
"""A pipe that separates table cells (one after a backslash is text)."""
_DEFINITION = re.compile(r" {0,3}\[[^\]]+\]:", re.MULTILINE)


def _plain_table(text: str) -> str | None:
    """A table whose cells are plain text (`_SYNTAX` absent, but for backslash escapes) and whose
    delimiter row sets no alignment, as markdown-it renders it; None for any other."""
    lines = text.splitlines()
    if len(lines) < 2 or set(lines[1].replace("|", "").strip()) != {"-"}:
        return None
    rows = [_plain_cells(line) for line in (lines[0], *lines[2:])]
    if any(r is None for r in rows):
        return None
    head, *body = rows
    assert head is not None
    if len(_plain_cells(lines[1]) or ()) != len(head):
        return None
    width = len(head)
    out = ["<table>\n<thead>\n<tr>\n"]
    out += [f"<th>{escapeHtml(c)}</th>\n" for c in head]
    out.append("</tr>\n</thead>\n")
    if body:
        out.append("<tbody>\n")
        for row in body:
            assert row is not None
            cells = (row + [""] * width)[:width]
            out.append("<tr>\n" + "".join(f"<td>{escapeHtml(c)}</td>\n" for c in cells) + "</tr>\n")
        out.append("</tbody>\n")
    out.append("</table>\n")
    return "".join(out)


def _plain_cells(line: str) -> list[str] | None:
    """The cells of a table row `| a | b |` when each is plain text, else None. Escaped
    punctuation (`\\_`, `\\<`, `\\|`, as `impactlab.text.md_text` writes it) is plain text."""
    row = line.strip()
    if not (row.startswith("|") and row.endswith("|")) or row.endswith("\\|") or len(row) < 2:
        return None
    cells = []
    for cell in _split_row(row[1:-1]):
        text = cell.strip()
        escaped = "\\" in text
        if _SYNTAX.search(_ESCAPED.sub("\0", text) if escaped else text):
            return None
        cells.append(_ESCAPED.sub(r"\1", text) if escaped else text)
    return cells


def _split_row(row: str) -> list[str]:
    """A row's cells as markdown-it's table rule splits them (`escapedSplit`): a pipe after a
    backslash is text, and that backslash is dropped."""
    return [c.replace("\\|", "|") for c in _PIPE.split(row)]


def _closes(line: str, fence: str) -> bool:
    """Whether `line` closes a code fence opened with `fence` (CommonMark)."""
    closing = _FENCE.match(line)
    if closing is None:
        return False
    mark = closing.group(1)
    return mark[0] == fence[0] and len(mark) >= len(fence) and not line[closing.end() :].strip()


class _Lines(Sequence[str]):
    """A text's lines with their ends (as `str.splitlines(keepends=True)` cuts them), each
    read from the text when it is indexed: only where each line ends is kept (the report of
    20,000 runs is 17 MB of text; its list of lines took 22 MB more)."""

    def __init__(self, text: str) -> None:
        self._text = text
        self._ends = array("q", (m.end() for m in _LINE_END.finditer(text)))
        if not self._ends or self._ends[-1] < len(text):
            self._ends.append(len(text))  # the last line, without an end

    def __len__(self) -> int:
        return len(self._ends) if self._text else 0

    @overload
    def __getitem__(self, i: int) -> str: ...
    @overload
    def __getitem__(self, i: slice) -> list[str]: ...
    def __getitem__(self, i: int | slice) -> str | list[str]:
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        if not 0 <= i < len(self):
            raise IndexError(i)
        return self._text[self._ends[i - 1] if i else 0 : self._ends[i]]


_LINE_END = re.compile("\r\n|[\n\r\v\f\x1c\x1d\x1e\x85\u2028\u2029]")
"""Where `str.splitlines` cuts a line."""


def _table_at(lines: Sequence[str], i: int) -> bool:
    """Whether a table (a row, then its delimiter row) starts at line i."""
    return (
        lines[i].startswith("|")  # at the margin: a table of the page, not of a list item
        and i + 1 < len(lines)
        and bool(_DELIMITER.match(lines[i + 1].strip()))
    )


def _stitched(part: str, html_text: str) -> str:
    """A table slice's HTML as its part of the one table."""
    if part in ("first", "middle"):
        html_text = html_text.removesuffix(_TAIL)
    if part in ("middle", "last"):
        html_text = html_text[html_text.index(_HEAD) + len(_HEAD) :]
    return html_text


def _local(src: str) -> str | None:
    """The relative file path a link or image names, or None (a URL, an anchor)."""
    parts = urlsplit(src)
    if parts.scheme or parts.netloc or not parts.path:
        return None
    return unquote(parts.path)


def _figure(folder: Path, src: str) -> tuple[bytes, str] | str:
    """The bytes and media type of the figure `src` names, or why it is not embedded: only an
    image file (`FIGURE_TYPES`) inside `folder` (after resolving links), a regular file of at
    most `MAX_FIGURE_BYTES`, is ever read."""
    path = _local(src)
    if path is None or path.startswith("/"):
        return "not a file in the report's folder"
    root = folder.resolve()
    file = (root / path).resolve()
    mime = FIGURE_TYPES.get(file.suffix.lower())
    if not file.is_relative_to(root) or mime is None:
        return "not a figure file in the report's folder"
    try:
        info = file.stat()
        if not stat.S_ISREG(info.st_mode):
            return "not a regular file"
        if info.st_size > MAX_FIGURE_BYTES:
            return f"over {MAX_FIGURE_BYTES >> 20} MiB"
        with open(file, "rb") as stream:
            data = stream.read(MAX_FIGURE_BYTES + 1)
    except OSError:
        return "missing"
    if len(data) > MAX_FIGURE_BYTES:
        return f"over {MAX_FIGURE_BYTES >> 20} MiB"
    return data, mime


def _embed(tokens: list[Token], folder: Path) -> list[str]:
    """Inline every figure as a data URI, and turn any other image into its alt text (the
    page loads nothing); returns the images not embedded, with the reason."""
    refused = []
    for token in tokens:
        children = token.children or []
        for i, child in enumerate(children):
            if child.type != "image":
                continue
            src = str(child.attrGet("src") or "")
            found = _figure(folder, src)
            if isinstance(found, str):
                refused.append(src if found == "missing" else f"{src} ({found})")
                alt = Token("text", "", 0)
                alt.content = "".join(c.content for c in child.children or [])
                children[i] = alt
                continue
            data, mime = found
            child.attrSet("src", f"data:{mime};base64,{base64.b64encode(data).decode()}")
    return refused


def _rendered(markdown: str, folder: Path, missing: list[str]) -> Iterator[str]:
    """The page's body, piece by piece (`_pieces`); figures not found are added to
    `missing`."""
    md = _parser()
    env: dict[str, Any] = {}
    for part, text in _pieces(markdown, tables=True):
        plain = _plain_table(text) if part else None  # a slice of plain rows: written as is
        if plain is not None:
            yield _stitched(part, plain)
            continue
        tokens = md.parse(text, env)
        missing += _embed(tokens, folder)
        yield _stitched(part, md.renderer.render(tokens, md.options, env))
        del tokens


def _frame(title: str, missing: list[str]) -> tuple[str, str]:
    """The page before its body (with the note on missing figures) and after it."""
    note = ""
    if missing:
        items = "".join(f"<li>{html.escape(m)}</li>" for m in missing)
        note = f"<p><strong>Figures missing when this page was made:</strong></p><ul>{items}</ul>"
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f'<meta http-equiv="Content-Security-Policy" content="{CSP}">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{html.escape(title)}</title>\n<style>{STYLE}</style>\n</head>\n"
        f"<body>\n{note}"
    ), "</body>\n</html>\n"


def report_html(markdown: str, folder: Path, title: str = "impactlab report") -> str:
    """The Markdown `markdown` (whose relative paths are relative to `folder`) as one page.

    It is parsed piece by piece (`_pieces`), so that no syntax tree of the whole report
    exists at once: memory stays bounded by a section or a slice of a table, whatever the
    number of runs.
    """
    missing: list[str] = []
    body = "".join(_rendered(markdown, folder, missing))
    head, tail = _frame(title, missing)
    return head + body + tail


def write_report_html(report_md: Path) -> Path:
    """Write `report.html` beside `report_md` (atomically); returns its path.

    The body is written piece by piece into a temporary file, then the page around it: the
    page is never held whole in memory.
    """
    text = report_md.read_text(encoding="utf-8")
    heading = _TITLE.search(text)
    first = heading.group(0) if heading else "# impactlab report"
    target = report_md.with_suffix(".html")
    body = temporary_path(report_md.with_suffix(".body.html"))
    missing: list[str] = []
    try:
        with open(body, "w", encoding="utf-8") as stream:
            for piece in _rendered(text, report_md.parent, missing):
                stream.write(piece)
        del text
        head, tail = _frame(first[2:].strip(), missing)
        with atomic_path(target) as tmp, open(tmp, "w", encoding="utf-8") as out:
            out.write(head)
            with open(body, encoding="utf-8") as written:
                shutil.copyfileobj(written, out)
            out.write(tail)
    finally:
        body.unlink(missing_ok=True)
    return target
