"""The lab's report as a student hands it in: printed to PDF by headless Chromium it has at most
12 pages; in the printed layout no table is wider than the page (nothing is cut); each
handout step is answered in its first sentence; no run is reported twice."""

from __future__ import annotations

import html
import json
import re
import shutil
import tempfile
from pathlib import Path

import pytest
from markdown_it import MarkdownIt
from test_report_html import browse
from test_report_writers import cells

from impactlab.analyze.report.html import CSP
from impactlab.lab import run_lab

pytestmark = pytest.mark.slow  # the handout's experiments recorded and analyzed, Chromium

MAX_PAGES = 12
PRINTABLE_PX = round((210 - 2 * 14) / 25.4 * 96)  # A4 less the page's margins, CSS pixels
WIDTHS = """<script>
window.addEventListener("load", () => {
  const page = document.documentElement.clientWidth;
  document.body.dataset.check = JSON.stringify({
    page,
    tables: [...document.querySelectorAll("table")].map((t) => t.getBoundingClientRect().right),
    images: [...document.images].map((i) => i.getBoundingClientRect().right),
  });
});
</script>"""
STEP = re.compile(r"^## (Step \d): .*?\n\n(.*?)(?:\n\n|$)", re.S | re.M)


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("lab")
    run_lab(out, replay=False, calibration="none")
    return out / "results"


def pages(pdf: Path) -> int:
    return len(re.findall(rb"/Type\s*/Page\b", pdf.read_bytes()))


@pytest.mark.parametrize("name", ["report", "report-appendix"])
def test_printed_report_fits_and_no_table_is_cut(results, tmp_path, name):
    page = results / f"{name}.html"
    pdf = tmp_path / f"{name}.pdf"
    browse(page, tmp_path, f"--print-to-pdf={pdf}", "--no-pdf-header-footer")
    shutil.copy(pdf, Path(tempfile.gettempdir()) / f"impactlab-{name}.pdf")  # to look at
    if name == "report":
        assert 1 < pages(pdf) <= MAX_PAGES
    # the printed layout: the print rules applied on screen, at the printable width
    text = page.read_text(encoding="utf-8").replace("@media print", "@media all")
    policy = f'content="{CSP}"'
    text = text.replace(policy, f"content=\"{CSP}; script-src 'unsafe-inline'\"")
    checked = tmp_path / "print.html"
    checked.write_text(text.replace("</body>", WIDTHS + "</body>"), encoding="utf-8")
    dom = browse(checked, tmp_path, "--dump-dom", f"--window-size={PRINTABLE_PX},1200")
    found = re.search(r'data-check="([^"]*)"', dom)
    assert found, "the page's load handler did not run"
    check = json.loads(html.unescape(found.group(1)))
    assert check["page"] <= PRINTABLE_PX and check["tables"]
    assert max(check["tables"] + check["images"]) <= check["page"] + 1, check


def test_each_step_is_answered_in_its_first_sentence(results):
    report = (results / "report.md").read_text()
    answers = dict(STEP.findall(report))
    assert list(answers) == ["Step 1", "Step 2", "Step 3", "Step 4"]
    for step, paragraph in answers.items():
        first = re.split(r"(?<=[.)])\*\* |(?<=\.) (?=[A-Z])", paragraph.strip("*"), maxsplit=1)[0]
        assert re.match(r"(Yes|No)\b", first), (step, first)  # the handout's run answer
        assert re.search(r"\d", first), (step, first)  # with its number
        assert len(first.split()) <= 60, (step, len(first.split()))


def test_every_table_whole_with_human_headers(results):
    md = MarkdownIt("commonmark", {"html": False}).enable("table")
    for name in ("report", "report-appendix"):
        text = (results / f"{name}.md").read_text()
        for page in (md.render(text), (results / f"{name}.html").read_text()):
            rows = cells(page).rows
            assert rows and all(len(r) > 1 for r in rows)
            headers = [r for r in rows if r and r[0] in ("Run", "Experiment", "Outcome", "Step")]
            assert headers, name
        for number in re.findall(r"\d[\d.]*e[-+]\d+", text):
            pytest.fail(f"{name}: {number} printed with an exponent")
        for header in re.findall(r"^\| (.+) \|\n\|---", text, re.M):
            assert not re.search(r"[a-z]_[a-z]", header), header  # no code names


def test_no_run_is_reported_twice(results):
    report = (results / "report.md").read_text()
    assert "free_fall is the same run as drop: ball released at z = 3 m" in report
    step1 = report[report.index("## Step 1") : report.index("## Step 2")]
    assert "| free_fall |" not in step1  # its row is the 3 m drop's, once
    assert step1.count("| drop: ball released at z = 3 m = free_fall |") == 1
    appendix = (results / "report-appendix.md").read_text()
    assert "energy-free_fall" not in appendix
