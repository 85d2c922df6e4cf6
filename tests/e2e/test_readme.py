"""The README's images and local links name files of the repository; its benchmark tables
are the results files'."""

from __future__ import annotations

import re

from paths import ROOT


def test_readme_images_and_links_exist():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#\s]+)\)", text)
    local = [t for t in targets if "://" not in t]
    assert "docs/report-restitution.png" in local  # the figure from the lab report
    missing = [t for t in local if not (ROOT / t).exists()]
    assert missing == []


def test_readme_results_are_those_of_the_results_files():
    """The README's performance and scale tables are the benchmark's results files (all but
    their title), copied by the run that wrote them: they cannot drift apart."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for name in ("bench.md", "scale.md"):
        text = (ROOT / "benchmarks" / "results" / name).read_text(encoding="utf-8")
        begin = f"<!-- benchmarks/results/{name}: begin -->\n"
        end = f"<!-- benchmarks/results/{name}: end -->"
        assert readme.count(begin) == 1 and readme.count(end) == 1, name
        shown = readme.split(begin, 1)[1].split(end, 1)[0]
        assert shown == "\n".join(text.splitlines()[2:]).strip() + "\n", name
        assert "| verdict |" in shown, name
