"""The README's images and local links name files of the repository."""

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
