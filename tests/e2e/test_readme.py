"""The README's and docs' images and local links name files of the repository; the benchmark
tables of docs/performance.md are the results files'; the README stays short; the lock it
installs from holds only pins, one for every declared dependency."""

from __future__ import annotations

import re

import pytest
from paths import ROOT

PAGES = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", *sorted((ROOT / "docs").glob("*.md"))]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_images_and_links_exist(page):
    text = re.sub(r"(?s)```.*?```|`[^`\n]*`", "", page.read_text(encoding="utf-8"))  # no code
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)\s]*)?\)", text)
    local = [t for t in targets if "://" not in t]
    if page.name == "README.md":
        assert "docs/report-restitution.png" in local  # the figure from the lab report
    missing = [t for t in local if not (page.parent / t).exists()]
    assert missing == []


def test_the_readme_is_short_and_links_every_docs_page():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.split()) <= 1500  # issue 37: a README a newcomer finishes
    unlinked = [p.name for p in (ROOT / "docs").glob("*.md") if f"](docs/{p.name})" not in text]
    assert unlinked == []


def test_the_performance_page_results_are_those_of_the_results_files():
    """docs/performance.md's benchmark and scale tables are the results files (all but their
    title), copied by the run that wrote them (benchmarks/results.py): they cannot drift."""
    page = (ROOT / "docs" / "performance.md").read_text(encoding="utf-8")
    for name in ("bench.md", "scale.md"):
        text = (ROOT / "benchmarks" / "results" / name).read_text(encoding="utf-8")
        begin = f"<!-- benchmarks/results/{name}: begin -->\n"
        end = f"<!-- benchmarks/results/{name}: end -->"
        assert page.count(begin) == 1 and page.count(end) == 1, name
        shown = page.split(begin, 1)[1].split(end, 1)[0]
        assert shown == "\n".join(text.splitlines()[2:]).strip() + "\n", name
        assert "| verdict |" in shown, name


def test_the_lock_holds_only_pins():
    """The README's installs print no pip warning: every line of requirements.lock is a pin
    `name==version` or a comment, so no index, find-links or local path of the machine that
    wrote it (issue 37: 84 "Location ... is ignored" warnings) can come back."""
    lines = (ROOT / "requirements.lock").read_text(encoding="utf-8").splitlines()
    pin = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*==[A-Za-z0-9.+!-]+")
    odd = [line for line in lines if line.strip() and not line.lstrip().startswith("#")]
    odd = [line for line in odd if not pin.fullmatch(line)]
    assert odd == []
    assert sum(bool(pin.fullmatch(line)) for line in lines) > 50


def test_the_lock_pins_every_declared_dependency():
    """`just lock` compiles every extra: a dependency added to pyproject.toml without it (the
    zoo extra was) is missing here, and `pip install -c requirements.lock` leaves it free."""
    import tomllib

    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    declared = [*project["dependencies"]]
    declared += [r for extra in project["optional-dependencies"].values() for r in extra]
    text = (ROOT / "requirements.lock").read_text(encoding="utf-8")
    pinned = {canonicalize_name(m) for m in re.findall(r"(?m)^([A-Za-z0-9][\w.-]*)==", text)}
    names = {canonicalize_name(Requirement(r).name) for r in declared} - {"impactlab"}
    assert len(names) > 20
    assert sorted(names - pinned) == []


def test_the_experiments_page_lists_every_spec():
    """docs/experiments.md's table has a row for every spec that ships (a new one is never
    missing from it)."""
    text = (ROOT / "docs" / "experiments.md").read_text(encoding="utf-8")
    folder = ROOT / "experiments"
    specs = [p.relative_to(folder).as_posix() for p in sorted(folder.rglob("*.toml"))]
    assert len(specs) > 5
    assert [s for s in specs if f"\n| `{s}` |" not in text] == []
