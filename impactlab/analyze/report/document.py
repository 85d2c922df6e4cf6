"""The report (report.md, report.html) and its appendix, built from the tables as blocks."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import polars as pl

from impactlab.analyze.report import findings as F
from impactlab.analyze.report import html, markdown, questions
from impactlab.analyze.report.appendix import appendix
from impactlab.analyze.report.blocks import (
    Block,
    Bullets,
    Column,
    Contents,
    Document,
    Heading,
    Link,
    Paragraph,
    Strong,
    Table,
    footnoted,
    span,
)
from impactlab.analyze.report.context import Tables, repeat_notes
from impactlab.analyze.report.handout import as_written
from impactlab.files import write_text
from impactlab.logs.format import NOTHING_MOVES
from impactlab.logs.labels import parameter_words
from impactlab.show import number
from impactlab.text import visible

TITLE = "Impact lab: free fall and impact"
STEPS: tuple[tuple[str, Callable[[Tables], questions.Answer]], ...] = (
    ("Step 1: Is energy conserved in flight and lost at contact?", questions.energy),
    (
        "Step 2: Is e constant across bounces, and does it depend on the drop height?",
        questions.restitution,
    ),
    (
        "Step 3: Is momentum conserved in a collision, and the energy lost as predicted?",
        questions.collision,
    ),
    (
        "Step 4: As the contact approaches elastic, do the velocities approach the elastic answer?",
        questions.study,
    ),
)


def answers(t: Tables) -> list[questions.Answer]:
    """Each handout step's answer; a fault in one becomes its "Not answered" with the error."""
    out = []
    for title, build in STEPS:
        try:
            out.append(build(t))
        except F.WORDING_ERRORS as exc:
            out.append(questions.not_answered(F.failed(title.split(":")[0], exc)))
    return out


def report(t: Tables, replies: Sequence[questions.Answer]) -> Document:
    """The report to hand in: the experiments, an answer per step, the handout as written, a
    conclusion; the details are in the appendix."""
    n_exp = t.all_runs["experiment"].n_unique()
    intro = (
        f"{t.runs.height} runs analyzed from the logs of {n_exp} experiments"
        + (f"; {len(t.failed)} input(s) could not be read" if t.failed else "")
        + (f"; {_repeats(t)}" if t.same else "")
        + ". Units: SI."
        + _still(t)
        + ("" if t.figures_asked else " No figures were drawn (--no-figures).")
        + " Every table and figure, the method and the files are in "
    )
    doc = Document(TITLE, [Paragraph((intro, Link("the appendix", questions.APPENDIX), "."))])
    doc.blocks += _problems(t)
    doc.blocks += [Contents(), Heading("Experiments"), *_experiments(t)]
    for (title, _), answer in zip(STEPS, replies, strict=True):
        doc.blocks += [Heading(title), Paragraph(tuple(answer.lead)), *answer.evidence]
    doc.blocks += as_written(t)
    steps = [
        (Strong(title.split(":")[0] + ":"), " " + a.finding)
        for (title, _), a in zip(STEPS, replies, strict=True)
    ]
    doc.blocks += [Heading("Conclusion"), Bullets(tuple(steps))]
    return doc


def _still(t: Tables) -> str:
    """The sentence saying that nothing moves, when nothing moves in any run."""
    if not t.still:
        return ""
    drawn = ", and no figure to draw" if t.figures_asked else ""
    return (
        f" In every run {NOTHING_MOVES}; there is no flight, bounce or collision to measure{drawn}."
    )


def _repeats(t: Tables) -> str:
    labels = dict(t.all_runs.select("run_id", "run").iter_rows())
    pairs = [f"{labels[r]} is the same run as {labels[k]}" for r, k in list(t.same.items())[:3]]
    return ", ".join(pairs) + " and is reported once"


def _problems(t: Tables) -> list[Block]:
    """The inputs not analyzed and the partial logs, if any."""
    out: list[Block] = []
    if t.failed:
        rows = [(visible(name), visible(why)) for name, why in t.failed]  # bytes not UTF-8
        failed = pl.DataFrame(rows, schema=["input", "why"], orient="row")
        cols = (Column("input", "Input"), Column("why", "Why it was not analyzed"))
        table = Table(failed, cols, source="summary.json", limit=questions.MAIN_ROWS)
        out += [Paragraph(("Inputs not analyzed:",)), table]
    partial = t.runs.filter(pl.col("partial"))
    if partial.height:
        cols = (Column("run_id", "Run id (log)"), Column("problems", "Damaged or missing"))
        table = Table(partial, cols, source="runs.parquet", limit=questions.MAIN_ROWS)
        why = "Partial logs (damaged or incomplete; what could be read was analyzed):"
        out += [Paragraph((why,)), table]
    return out


def _experiments(t: Tables) -> list[Block]:
    """Every experiment's parameters, one row each."""
    rows = []
    repeats = repeat_notes(t)
    for (name,), runs in t.all_runs.group_by("experiment", maintain_order=True):
        briefs = [t.briefs[r] for r in runs["run_id"] if r in t.briefs]
        gravity = _one({number(b.gravity_mps2, None) for b in briefs})
        simulation = [
            _one(set(runs["integrator"].to_list())),
            f"dt = {_one({number(v, None) for v in runs['timestep_s']})} s",
            f"g = {gravity} m/s²" if gravity else "",
            _every(runs),
        ]
        rows.append(
            {
                "experiment": name,
                "runs": runs.height,
                "swept": "; ".join(_swept(p, runs[p]) for p in t.params.get(str(name), [])),
                "bodies": _one({b.bodies for b in briefs}),
                "start": _start(runs),
                "contact": _one({b.contact for b in briefs}),
                "simulation": ", ".join(w for w in simulation if w),
                "note": " ".join(dict.fromkeys(repeats[r] for r in runs["run_id"] if r in repeats)),
            }
        )
    frame, notes = footnoted(pl.DataFrame(rows, infer_schema_length=None), "note")
    cols = (
        Column("experiment", "Experiment"),
        Column("runs", "Runs"),
        Column("swept", "Swept"),
        Column("bodies", "Bodies"),
        Column("start", "Start"),
        Column("contact", "Contact"),
        Column("simulation", "Simulation"),
        Column("note", "Note"),
    )
    return [Table(frame, cols, notes)]


def _swept(param: str, values: pl.Series) -> str:
    """A swept parameter and its values in words ("ball released at z = 1, 2, 3 m")."""
    shown = ", ".join(number(v, None) for v in values.unique(maintain_order=True).to_list())
    return parameter_words(param, shown)


def _every(runs: pl.DataFrame) -> str:
    every = _one({str(v) for v in runs["log_every"]})
    return "every step logged" if every == "1" else f"1 step in {every} logged"


def _one(values: set[str]) -> str:
    values.discard("")
    return values.pop() if len(values) == 1 else ("swept" if values else "")


def _start(runs: pl.DataFrame) -> str:
    heights = runs["drop_height_m"].to_list() if "drop_height_m" in runs.columns else []
    if span(heights):
        return f"dropped from {span(heights, 'm', None)} (lowest point)"
    v1, v2 = runs["v1n_before_mps"].drop_nulls(), runs["v2n_before_mps"].drop_nulls()
    if v1.len() and v2.len():
        return f"v1 = {span(v1.to_list(), '', None)}, v2 = {span(v2.to_list(), '', None)} m/s"
    return ""


def summary_answers(replies: Sequence[questions.Answer]) -> dict[str, str]:
    """The answers as plain text, for summary.json."""
    keys = ("energy", "restitution", "collision", "parameter_study")
    return {
        k: "".join(s if isinstance(s, str) else s.text for s in a.lead)
        for k, a in zip(keys, replies, strict=True)
    }


def write_reports(t: Tables, folder: Path, replies: Sequence[questions.Answer]) -> list[Path]:
    """Write report.md, report.html, report-appendix.md and report-appendix.html
    (`replies`: the answers, `answers(t)`)."""
    files = write_document(report(t, replies), folder / "report.md")
    budget = replies[0].whole
    return files + write_document(appendix(t, budget), folder / questions.APPENDIX)


def write_document(doc: Document, path: Path) -> list[Path]:
    """Write the document as `path` (Markdown) and beside it as .html."""
    page = path.with_suffix(".html")
    write_text(path, markdown.markdown(doc, path.parent))
    write_text(page, html.html(doc, path.parent))
    return [path, page]


def append_report_sections(path: Path, blocks: list[Block]) -> list[Path]:
    """Add sections at the end of a document `write_document` wrote, listed in its contents."""
    page = path.with_suffix(".html")
    headings = [b for b in blocks if isinstance(b, Heading)]
    text = path.read_text(encoding="utf-8")
    text = text.replace(
        markdown.CONTENTS_END, markdown.contents(headings) + markdown.CONTENTS_END, 1
    )
    added = "\n".join(markdown.block_markdown(b, path.parent, blocks) for b in blocks)
    write_text(path, text + "\n" + added)
    body = page.read_text(encoding="utf-8")
    body = body.replace(html.CONTENTS_END, html.contents(headings) + html.CONTENTS_END, 1)
    added = "".join(html.block_html(b, path.parent, blocks) for b in blocks)
    write_text(page, body.removesuffix(html.PAGE_END) + added + html.PAGE_END)
    return [path, page]
