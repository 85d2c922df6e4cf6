"""The report as one self-contained HTML page: report.md rendered, its figures embedded.

The page is what gets handed in or opened in a browser: every image the Markdown shows is
inlined as a data URI (so the page can be mailed or moved alone), headings get the ids that
GitHub gives them (so the report's in-page links work in both), and links to other files
(tables, replays, the calibration details) stay relative, working beside the results.
"""

from __future__ import annotations

import base64
import html
import mimetypes
from pathlib import Path
from urllib.parse import unquote, urlsplit

from markdown_it import MarkdownIt
from markdown_it.token import Token
from mdit_py_plugins.anchors import anchors_plugin

from impactlab.files import write_text

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


def _parser() -> MarkdownIt:
    return MarkdownIt("commonmark").enable("table").use(anchors_plugin, max_level=6)


def _local(src: str) -> str | None:
    """The relative file path a link or image names, or None (a URL, an anchor)."""
    parts = urlsplit(src)
    if parts.scheme or parts.netloc or not parts.path:
        return None
    return unquote(parts.path)


def _embed(tokens: list[Token], folder: Path) -> list[str]:
    """Inline every local image as a data URI; returns the images that could not be read."""
    missing = []
    for token in tokens:
        for child in token.children or []:
            if child.type != "image":
                continue
            src = str(child.attrGet("src") or "")
            path = _local(src)
            if path is None:
                continue
            file = folder / path
            try:
                data = file.read_bytes()
            except OSError:
                missing.append(src)
                continue
            mime = mimetypes.guess_type(file.name)[0] or "application/octet-stream"
            child.attrSet("src", f"data:{mime};base64,{base64.b64encode(data).decode()}")
    return missing


def report_html(markdown: str, folder: Path, title: str = "impactlab report") -> str:
    """The Markdown `markdown` (whose relative paths are relative to `folder`) as one page."""
    md = _parser()
    tokens = md.parse(markdown)
    missing = _embed(tokens, folder)
    body = md.renderer.render(tokens, md.options, {})
    note = ""
    if missing:
        items = "".join(f"<li>{html.escape(m)}</li>" for m in missing)
        note = f"<p><strong>Figures missing when this page was made:</strong></p><ul>{items}</ul>"
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        f"<title>{html.escape(title)}</title>\n<style>{STYLE}</style>\n</head>\n"
        f"<body>\n{note}{body}</body>\n</html>\n"
    )


def write_report_html(report_md: Path) -> Path:
    """Write `report.html` beside `report_md` (atomically); returns its path."""
    text = report_md.read_text(encoding="utf-8")
    first = next(
        (line for line in text.splitlines() if line.startswith("# ")), "# impactlab report"
    )
    page = report_html(text, report_md.parent, title=first[2:].strip())
    return write_text(report_md.with_suffix(".html"), page)
