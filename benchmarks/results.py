"""The benchmark's results file: every figure with its goal and verdict, and where it was
measured (machine, date, load average, versions), as a Markdown table.

Each run of `bench.py` (or `bench.py --scale`) overwrites its file under
`benchmarks/results/` (`bench.md`, `scale.md`): the figures of one file come from one run.
"""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

FOLDER = Path(__file__).resolve().parent / "results"


def verdict(ok: bool) -> str:
    """A goal's verdict, as the results say it."""
    return "met" if ok else "not met"


def load_average() -> str:
    """The 1, 5 and 15 minute load averages of this machine."""
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())


def machine() -> str:
    """The machine and the versions that matter to the figures."""
    import mujoco
    import numpy
    import polars

    return (
        f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"MuJoCo {mujoco.__version__}, numpy {numpy.__version__}, polars {polars.__version__}"
    )


def _commit() -> str:
    if os.environ.get("BENCH_COMMIT"):  # a copy of the tree measured outside its checkout
        return os.environ["BENCH_COMMIT"]
    try:
        done = subprocess.run(
            ["git", "describe", "--always", "--dirty"],
            cwd=FOLDER.parent,
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return done.stdout.strip() or "unknown"


@dataclass
class Results:
    """Figures gathered as a benchmark runs, written as one Markdown file at the end."""

    title: str
    command: str
    rows: list[tuple[str, str, str, str, str]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    tables: list[tuple[list[str], list[list[str]]]] = field(default_factory=list)
    started: str = field(default_factory=lambda: _now())
    load_start: str = field(default_factory=load_average)

    def add(self, section: str, what: str, measured: str, goal: str = "", ok: bool | None = None):
        """One figure: what, as measured, its goal (or baseline) and, with a goal, `ok`."""
        self.rows.append((section, what, measured, goal, "" if ok is None else verdict(ok)))

    def table(self, header: list[str], rows: list[list[str]]) -> None:
        """A table of figures (without goals) printed before the table of goals."""
        self.tables.append((header, rows))

    def note(self, text: str) -> None:
        """A sentence under the table (how something was measured)."""
        self.notes.append(text)

    def markdown(self) -> str:
        """The results as Markdown: where, when, then the table and the notes."""
        lines = [
            f"# {self.title}",
            "",
            f"Written by `{self.command}` (overwritten by each run; do not edit by hand).",
            "",
            f"- machine: {machine()}",
            f"- impactlab: {_commit()}",
            f"- started: {self.started}, finished: {_now()}",
            f"- load average (1, 5, 15 min): {self.load_start} at the start, "
            f"{load_average()} at the end",
            "",
        ]
        for header, rows in self.tables:
            lines += [_row(header), _row(["---"] * len(header)), *map(_row, rows), ""]
        lines += [
            "| section | what | measured | goal or baseline | verdict |",
            "|---|---|---|---|---|",
        ]
        lines += [_row(list(row)) for row in self.rows]
        if self.notes:
            lines += ["", *self.notes]
        return "\n".join(lines) + "\n"

    def write(self, name: str) -> Path:
        """Write (overwrite) `benchmarks/results/<name>` and its copy in docs/performance.md
        (`to_page`); its path."""
        FOLDER.mkdir(exist_ok=True)
        path = FOLDER / name
        text = self.markdown()
        path.write_text(text, encoding="utf-8")
        to_page(name, text)
        return path


PAGE = FOLDER.parent.parent / "docs" / "performance.md"


def page_block(text: str) -> str:
    """What docs/performance.md shows of a results file: all of it but its title."""
    return "\n".join(text.splitlines()[2:]).strip() + "\n"


def markers(name: str) -> tuple[str, str]:
    """The comments around a results file's copy in docs/performance.md."""
    return f"<!-- benchmarks/results/{name}: begin -->", f"<!-- benchmarks/results/{name}: end -->"


def to_page(name: str, text: str) -> None:
    """Put the results `text` of `name` between its markers in docs/performance.md (its
    tables come from the same run as the file); nothing when the page has no markers."""
    if not PAGE.exists():
        return
    page = PAGE.read_text(encoding="utf-8")
    begin, end = markers(name)
    if begin not in page or end not in page:
        return
    head, rest = page.split(begin, 1)
    _, tail = rest.split(end, 1)
    PAGE.write_text(f"{head}{begin}\n{page_block(text)}{end}{tail}", encoding="utf-8")


def _now() -> str:
    return datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")


def _row(cells: list[str]) -> str:
    return "| " + " | ".join(_cell(c) for c in cells) + " |"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")
