"""The report's two writers: every text and cell escaped by the writer, every table row as many
cells as its header in report.md (read by a CommonMark parser with tables) and report.html,
numbers at sensible precision, long tables cut with their count, figures only from inside
the report's folder."""

from __future__ import annotations

import os
import re
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from markdown_it import MarkdownIt
from matplotlib import image

from impactlab.analyze.report import blocks, html, markdown
from impactlab.analyze.report.blocks import (
    Bullets,
    Column,
    Contents,
    Document,
    Figure,
    Heading,
    Link,
    Paragraph,
    Strong,
    Table,
    footnoted,
)
from impactlab.analyze.report.document import append_report_sections, write_document
from impactlab.show import NOTHING, TIMES, html_table, number

NAMES = [
    "a|b",
    "|v1'_elastic|",
    "<script>alert(1)</script>",
    "two\nlines",
    "back`tick",
    "![s](/etc/passwd)",
    "# heading",
    "1. item",
    "- dash",
    "$\\frac{1}{2}$",
    "**bold** _em_",
    "end\\",
    "",
]


class Cells(HTMLParser):
    """The cells of each table row of an HTML text, and every text shown."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[list[str]] = []
        self.text: list[str] = []
        self.tags: list[str] = []
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        if tag == "tr":
            self.rows.append([])
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self.rows[-1].append("".join(self._cell))
            self._cell = None

    def handle_data(self, data):
        self.text.append(data)
        if self._cell is not None:
            self._cell.append(data)


def cells(page: str) -> Cells:
    parser = Cells()
    parser.feed(page)
    return parser


def hostile_document() -> Document:
    frame = pl.DataFrame({"name": NAMES, "x": [float(i) * 1e-15 for i in range(len(NAMES))]})
    frame, notes = footnoted(frame.with_columns(pl.col("name").alias("note")), "note")
    columns = (
        Column("name", "Name | with <pipe>"),
        Column("x", "Value", "J"),
        Column("note", "Note"),
    )
    said = tuple(
        (name, Strong(name), Link(name + "!", "#a-heading"), "!", Link("x", "other.md#b c"))
        for name in NAMES
    )
    return Document(
        "Title | <b>",
        [
            Contents(),
            Heading("A heading"),
            Bullets(said),
            Table(frame, columns, notes),
            *[Paragraph((n,)) for n in NAMES],
        ],
    )


def test_every_row_has_as_many_cells_as_its_header_whatever_the_names(tmp_path):
    doc = hostile_document()
    md = MarkdownIt("commonmark", {"html": False}).enable("table")
    for page in (md.render(markdown.markdown(doc, tmp_path)), html.html(doc, tmp_path)):
        rows = cells(page).rows
        assert len(rows) == 1 + len(NAMES)
        assert all(len(r) == len(rows[0]) == 3 for r in rows), rows
        assert [r[0].strip() for r in rows[1:]] == [n.replace("\n", "\\n") for n in NAMES]
        assert rows[0][0].strip() == "Name | with <pipe> "[:-1]


def test_no_name_becomes_markup_in_either_page(tmp_path):
    doc = hostile_document()
    md = MarkdownIt("commonmark", {"html": False}).enable("table")
    for page in (md.render(markdown.markdown(doc, tmp_path)), html.html(doc, tmp_path)):
        parsed = cells(page)
        assert "script" not in parsed.tags and "img" not in parsed.tags
        assert "<strong>bold</strong>" not in page and "<em>em</em>" not in page
        assert parsed.tags.count("h2") == 1 and "h1" in parsed.tags  # no name made a heading
        shown = "".join(parsed.text)
        for name in NAMES[:-1]:
            assert name.replace("\n", "\\n") in shown, name
    page = html.html(doc, tmp_path)
    assert '<a href="#a-heading">' in page and 'href="other.md#b%20c"' in page


def test_numbers_read_at_sensible_precision_in_the_report_and_in_a_notebook():
    assert number(7.105427357601002e-15) == f"7.11 {TIMES} 10⁻¹⁵"
    assert number(2.2092) == "2.21" and number(28.449) == "28.4" and number(0.0185) == "0.0185"
    assert number(0.99) == "0.990" and number(-0.0103) == "-0.0103" and number(0.0) == "0"
    assert number(0.0005, None) == "0.0005" and number(1e-5, None) == f"1 {TIMES} 10⁻⁵"
    assert number(3.0, None) == "3" and number(None) == NOTHING and number(float("nan")) == NOTHING
    assert number(12000) == "12,000" and number(True) == "yes"
    assert blocks.percent(0.8319) == "83.2 %" and blocks.span([0.801, 0.799]) == "0.799 to 0.801"
    for x in np.geomspace(1e-20, 1e20, 81):
        assert not re.search(r"\de[-+]?\d", number(float(x)))
    cells = html_table(["x"], [[7.105427357601002e-15], [None], [0.123456], ["\x1b[31m"]])
    assert re.findall("<td>(.*?)</td>", cells) == [
        f"7.105 {TIMES} 10⁻¹⁵",
        NOTHING,
        "0.1235",
        "\\x1b[31m",
    ]


def test_a_long_table_is_cut_with_its_count_and_file(tmp_path, monkeypatch):
    monkeypatch.setattr(blocks, "REPORT_ROWS", 3)
    frame = pl.DataFrame({"run": [f"r{i}" for i in range(7)], "x": [float(i) for i in range(7)]})
    doc = Document(
        "T", [Table(frame, (Column("run", "Run"), Column("x", "X")), source="runs.parquet")]
    )
    for page in (markdown.markdown(doc, tmp_path), html.html(doc, tmp_path)):
        assert "The first 3 of 7 rows; all of them are in runs.parquet." in page
        assert "r2" in page and "r3" not in page
    short = Document("T", [Table(frame.head(3), (Column("run", "Run"),))])
    assert "The first" not in markdown.markdown(short, tmp_path)


def test_notes_become_footnotes_numbered_once_per_text():
    frame = pl.DataFrame({"note": ["", "long note", "other", "long note"]})
    marked, notes = footnoted(frame, "note")
    assert marked["note"].to_list() == ["", "1", "2", "1"] and notes == ("long note", "other")


def test_only_figure_files_inside_the_folder_are_embedded(tmp_path):
    folder = tmp_path / "results"
    (folder / "figures").mkdir(parents=True)
    image.imsave(folder / "figures/ok.png", np.random.default_rng(0).random((20, 30)))
    outside = tmp_path / "secret.png"
    outside.write_bytes((folder / "figures/ok.png").read_bytes())
    (folder / "figures/link.png").symlink_to(outside)
    (folder / "figures/notes.txt").write_text("SECRET")
    os.mkfifo(folder / "figures/fifo.png")  # opened blocking, a pipe would wait for a writer
    figures = [
        folder / "figures/ok.png",
        outside,
        folder / "figures/link.png",
        folder / "figures/notes.txt",
        folder / "figures/fifo.png",
        folder / "figures/gone.png",
        Path("/dev/zero"),
    ]
    page = html.html(Document("F", [Figure(p, p.name) for p in figures]), folder)
    assert page.count('src="data:image/png;base64,') == 1
    assert page.count("Figure not shown") == len(figures) - 1 and "SECRET" not in page


def test_sections_appended_are_listed_in_the_contents(tmp_path):
    path = tmp_path / "doc.md"
    write_document(Document("D", [Contents(), Heading("First"), Paragraph(("one",))]), path)
    append_report_sections(path, [Heading("Added <b>"), Paragraph(("two | <i>",))])
    text, page = path.read_text(), path.with_suffix(".html").read_text()
    assert text.index("[Added \\<b\\>](#added-b)") < text.index("## First") < text.index("## Added")
    assert (
        page.index('href="#added-b"')
        < page.index('<h2 id="first">')
        < page.index("two | &lt;i&gt;")
    )
    assert page.endswith(html.PAGE_END)


@pytest.mark.parametrize("name", ["a$b$c", "$\\undefinedcmd$"])
def test_names_in_figures_are_plain_text(name):
    from impactlab.plotting import plain, subplots

    fig, ax = subplots(figsize=(2, 1))
    ax.set_title(plain(name))
    fig.canvas.draw()  # math text would fail on the undefined command
    assert ax.title.get_text().replace("\\$", "$") == name
