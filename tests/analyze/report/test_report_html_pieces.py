"""report.html is rendered piece by piece (sections, slices of big tables) so that memory
stays bounded whatever the number of runs: the page must be the one the whole document
renders to, byte for byte."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import pytest
from markdown_it import MarkdownIt
from mdit_py_plugins.anchors import anchors_plugin

from impactlab.analyze.report import html as page
from impactlab.text import md_text


def whole(markdown: str, folder: Path) -> str:
    """The page body as one parse of the whole document renders it."""
    md = MarkdownIt("commonmark", {"html": False}).enable("table").use(anchors_plugin, max_level=6)
    tokens = md.parse(markdown)
    page._embed(tokens, folder)
    return md.renderer.render(tokens, md.options, {})


def table(rows: int, cols: int = 4, align: str = "---") -> str:
    head = "| " + " | ".join(f"c{j}" for j in range(cols)) + " |\n"
    head += "|" + "|".join([align] * cols) + "|\n"
    return head + "".join(
        "| " + " | ".join(f"r{i} `x{j}` [l](#runs)" for j in range(cols)) + " |\n"
        for i in range(rows)
    )


def plain_table(rows: int) -> str:
    """A table of cells the page writes without markdown-it: numbers, words, run ids."""
    head = "| run | run_id | bodies.ball.pos[2] | note | n |\n|---|---|---|---|---|\n"
    return head + "".join(
        f"| drop: ball at z = {i} m | bench_drop-ball.pos=0_0_{i}-9a8 | {i / 7:.4g} | "
        f'say "hi" \\| {i} | {"" if i % 5 else "-"} |\n'
        for i in range(rows)
    )


def hostile_table(rows: int) -> str:
    """A big table of names as `md_text` escapes them: plain text, written directly."""
    head = "| run | body | note |\n|---|---|---|\n"
    names = ["<img src=x onerror=alert(1)>", "![s](/etc/passwd)", "a|b\\|c", "_x_ *y* `z`", "&amp;"]
    return head + "".join(
        f"| {md_text(names[i % 5])} | {md_text(f'# {i}')} | {md_text(names[(i + 2) % 5])} |\n"
        for i in range(rows)
    )


def odd_table(rows: int) -> str:
    """A big table with one cell of inline syntax: its slices go through markdown-it."""
    body = plain_table(rows).splitlines(keepends=True)
    body[rows // 2 + 2] = "| *x* | a_b_ | [l](#runs) | &amp; `c` | \\_ |\n"
    body[rows // 3 + 2] = "| short row |\n"
    body[rows // 4 + 2] = "| 1 | 2 | 3 | 4 | 5 | 6 | 7 |\n"
    return "".join(body)


CASES = {
    "duplicate headings across sections": "# Report\n\n## Runs\n\ntext\n\n## Runs\n\n### Runs\n"
    "\n## Runs\n\n# Report\n",
    "a fence with blank lines, pipes and hashes": "## A\n\n```text\n| a | b |\n|---|---|\n\n"
    "# not a heading\n```\n\n## B\n\n~~~~\n```\n# still code\n~~~~\n\n## C\n",
    "big tables between blank lines": f"# T\n\nbefore\n\n{table(450)}\nafter\n\n"
    f"## Next\n\n{table(201, align=':--:')}\n{table(200)}\n{table(3)}",
    "a big table right after a paragraph line": f"# T\n\nintro line\n{table(300)}\n",
    "a big table ending the document": f"# T\n\n{table(401, cols=2)}",
    "a table followed by a paragraph line": f"# T\n\n{table(250)}tail line\n",
    "setext and lists": "Title\n=====\n\n- a\n\n- b\n\n  # in a list\n\n1. x\n2. y\n\nSub\n---\n",
    "images and links": "# F\n\n![here](fig.png)\n\n![gone](none.png)\n\n[to runs](#runs)\n\n"
    "## Runs\n",
    "no trailing newline": "## A\ntext",
    "plain big tables": f"# Runs\n\n{plain_table(650)}\n## Again\n\n{plain_table(201)}",
    "a big table with inline syntax": f"# Runs\n\n{odd_table(450)}\n",
    "a big table of escaped names": f"# Names\n\n{hostile_table(420)}\n",
    "raw html and escapes": "# H\n\n<script>x</script>\n\n<img src=x onerror=y> \\<b\\> \\\\| a\n\n"
    "| a | b |\n|---|---|\n| <i>x</i> | \\_y\\_ \\\\\\| z |\n",
    "a reference defined in another section": f"# A\n\nsee [the runs][r]\n\n{plain_table(300)}\n"
    "# B\n\n[r]: #runs\n",
    "a big table in a list item": "# L\n\n- item\n\n"
    + "".join("  " + r for r in table(300).splitlines(True)),
    "a big table in a quote": "# Q\n\n" + "".join("> " + r for r in table(300).splitlines(True)),
}


SLICED = {
    "big tables between blank lines",
    "a big table ending the document",
    "plain big tables",
    "a big table with inline syntax",
    "a big table of escaped names",
}


@pytest.mark.parametrize("name", list(CASES))
def test_pieces_render_as_the_whole_document(tmp_path, name):
    (tmp_path / "fig.png").write_bytes(b"\x89PNG\r\n\x1a\nnot really")
    text = CASES[name]
    out = page.report_html(text, tmp_path, "t")
    assert whole(text, tmp_path) in out
    slices = [part for part, _ in page._pieces(text) if part]
    assert bool(slices) == (name in SLICED)  # only tables of the page between blank lines


@pytest.mark.slow
def test_page_memory_does_not_grow_with_the_rows(tmp_path):
    """The peak of rendering a table of 1,500 rows stays within a few times its output
    above that of 200 rows (one parse of the whole table would hold a token tree of
    kilobytes per row)."""

    def peak(rows: int) -> tuple[int, int]:
        text = "# Runs\n\n" + table(rows, cols=6)
        tracemalloc.start()
        out = page.report_html(text, tmp_path, "t")
        top = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        return top, len(out)

    small, small_out = peak(200)
    big, big_out = peak(1500)
    added = big_out - small_out
    assert big - small < 6 * added, (small, big, added)
    tracemalloc.start()
    whole("# Runs\n\n" + table(1500, cols=6), tmp_path)
    old = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert old - small > 6 * added  # the bound tells the two ways apart


def test_plain_slices_are_written_without_markdown_it():
    """The plain tables' slices take the direct path, one with syntax does not."""
    fast = [
        page._plain_table(t) is not None for p, t in page._pieces(CASES["plain big tables"]) if p
    ]
    assert fast and all(fast)
    odd = [page._plain_table(t) is not None for p, t in page._pieces(odd_table(450)) if p]
    assert not all(odd)
    names = [page._plain_table(t) is not None for p, t in page._pieces(hostile_table(420)) if p]
    assert names and all(names)  # escaped names keep the fast path
