"""report.html: the report as one page with its figures embedded, opened in a real browser
(headless Chromium, Debian's `chromium`, which `.ci/run` installs)."""

from __future__ import annotations

import html
import json
import re
import shutil
import subprocess
import tempfile
from pathlib import Path
from urllib.parse import unquote, urlsplit

import paths
import pytest
from matplotlib import image

from impactlab.analyze.job import run_analysis
from impactlab.analyze.report.html import CSP

GOLDEN = paths.GOLDEN / "logs"
CHECK = """<script>
window.addEventListener("load", () => {
  const ids = new Set([...document.querySelectorAll("[id]")].map((e) => e.id));
  const anchors = [...document.querySelectorAll('a[href^="#"]')].map((a) => a.getAttribute("href"));
  document.body.dataset.check = JSON.stringify({
    images: [...document.images].map((i) => [i.alt, i.complete, i.naturalWidth]),
    missing: anchors.filter((h) => !ids.has(decodeURIComponent(h.slice(1)))),
    tables: document.querySelectorAll("table").length,
    figures_missing: document.body.innerText.split("Figure not shown").length - 1,
  });
});
</script>"""


def chromium() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        pytest.fail("headless Chromium is needed: apt-get install chromium (.ci/run does)")
    return found


def browse(page: Path, tmp: Path, *args: str) -> str:
    """Run headless Chromium on a page; its stdout."""
    cmd = [
        chromium(),
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--hide-scrollbars",
        f"--user-data-dir={tmp / 'chromium-profile'}",
        "--virtual-time-budget=10000",
        *args,
        page.as_uri(),
    ]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("html") / "results"
    run_analysis([GOLDEN], out, figures=True, report=True)
    return out


@pytest.mark.slow
def test_report_html_opens_in_chromium_with_every_figure_and_link(results, tmp_path):
    page = results / "report.html"
    text = page.read_text(encoding="utf-8")
    assert "<table>" in text and "data:image/png;base64," in text
    # every relative link names a file that exists beside the report
    for href in re.findall(r'href="([^"#][^"]*)"', text):
        parts = urlsplit(html.unescape(href))
        if not parts.scheme:
            assert (results / unquote(parts.path)).exists(), href
    policy = f'content="{CSP}"'
    assert policy in text  # the page runs no script: the check's own is allowed in a copy
    checked = tmp_path / "check.html"
    text = text.replace(policy, f"content=\"{CSP}; script-src 'unsafe-inline'\"")
    checked.write_text(text.replace("</body>", CHECK + "</body>"), encoding="utf-8")
    dom = browse(checked, tmp_path, "--dump-dom")
    found = re.search(r'data-check="([^"]*)"', dom)
    assert found, "the page's load handler did not run"
    check = json.loads(html.unescape(found.group(1)))
    markdown_images = len(re.findall(r"!\[", (results / "report.md").read_text()))
    assert check["figures_missing"] == 0
    assert len(check["images"]) == markdown_images > 0
    assert all(complete and width > 100 for _, complete, width in check["images"]), check
    assert check["missing"] == [] and check["tables"] > 0
    shot = tmp_path / "shot.png"
    browse(page, tmp_path, f"--screenshot={shot}", "--window-size=1200,1600")
    shutil.copy(shot, Path(tempfile.gettempdir()) / "impactlab-report-html.png")  # to look at
    pixels = image.imread(shot)
    assert pixels.shape[:2] == (1600, 1200)
    assert pixels[..., :3].std() > 0.05  # text, tables and figures: not a blank page
