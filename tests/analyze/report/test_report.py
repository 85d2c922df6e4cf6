"""The report a student hands in: answers first, a rubric table, readable run labels, every
handout question answered with a number."""

from __future__ import annotations

import re

import pytest
from specs import DIRECT, collision, drop, toml

from impactlab.analyze.job import run_analysis
from impactlab.analyze.tables.labels import parameter_words

DROP = toml(
    drop(
        "swept_drop",
        z=0.5,
        timestep=0.0005,
        contact=DIRECT,
        max_time=2.0,
        bounces=3,
        sweep={"ball.pos": [[0.0, 0.0, 0.4], [0.0, 0.0, 0.6]]},
    )
)
COLLISION = toml(
    collision(
        "swept_collision",
        timestep=0.00002,
        contact={"restitution": 0.5},
        max_time=0.5,
        sweep={"contact.restitution": [0.5, 0.9]},
    )
)
STEPS = ("step-1-energy", "step-2-restitution", "step-3-collision", "step-4-parameter-studies")
NUMBER = re.compile(r"\d+\.\d+|\d+ %|\d+e-\d+")


@pytest.fixture(scope="module")
def report(record_spec, tmp_path_factory) -> str:
    logs = record_spec("swept_drop", DROP) + record_spec("swept_collision", COLLISION)
    out = tmp_path_factory.mktemp("report")
    assert run_analysis(logs, out).exit_code == 0
    return (out / "report.md").read_text()


def _section(text: str, heading: str) -> str:
    """The text under `heading` up to the next heading of the same or a higher level."""
    level = heading.split(" ")[0]
    start = text.index(heading + "\n")
    rest = text[start + len(heading) + 1 :]
    ends = [m.start() for m in re.finditer(rf"^#{{1,{len(level)}}} ", rest, re.M)]
    return rest[: ends[0]] if ends else rest


@pytest.mark.slow
def test_rubric_then_answers_come_before_the_tables(report):
    headings = re.findall(r"^## (.+)$", report, re.M)
    assert headings[:3] == ["Rubric", "Answers", "Runs"]
    rubric = _section(report, "## Rubric")
    rows = re.findall(r"^\| ([A-Z][^|]+?) \| (\d+) \|", rubric, re.M)
    assert rows == [
        ("Energy analysis", "25"),
        ("Restitution measurement", "25"),
        ("Collision dynamics", "25"),
        ("Parameter study", "15"),
        ("Visualisation", "10"),
    ]
    for anchor in STEPS:  # each rubric item links its answer and its detail, and both exist
        assert f"(#{anchor}-answer)" in rubric and f"(#{anchor})" in rubric
    details = [h.lower().replace(":", "").replace(" ", "-") for h in headings]
    assert all(anchor in details for anchor in STEPS)


@pytest.mark.slow
def test_every_step_is_answered_with_a_number_a_figure_and_a_link(report):
    answers = _section(report, "## Answers")
    subsections = re.findall(r"^### (Step \d: .+) answer$", answers, re.M)
    assert len(subsections) == 4
    for title, anchor in zip(subsections, STEPS, strict=True):
        body = _section(answers, f"### {title} answer")
        question = re.search(r"\*\*Question\.\*\* (.+\?)", body)
        answer = re.search(r"\*\*Answer\.\*\* (.+)", body)
        assert question and answer, title
        assert "Not answered" not in answer.group(1), (title, answer.group(1))
        assert NUMBER.search(answer.group(1)), (title, answer.group(1))
        assert re.search(r"!\[[^\]]*\]\(figures/[^)]+\.png\)", body), title
        assert f"(#{anchor})" in body


@pytest.mark.slow
def test_run_labels_are_words_and_units_and_hashes_stay_in_the_runs_table(report):
    before_runs = re.sub(r"\]\([^)]*\)", "]", report[: report.index("## Runs")])  # not file names
    assert not re.search(r"-[0-9a-f]{8}\b", before_runs)
    assert "swept_drop: ball released at z = 0.4 m" in report
    assert "swept_collision: restitution = 0.9" in report
    runs = _section(report, "## Runs")
    assert re.search(
        r"\| swept_drop: ball released at z = 0\.6 m \| swept_drop-[^|]*-[0-9a-f]{8} \|", runs
    )
    after_runs = report[report.index("## Step 1: energy") :]
    assert not re.search(r"`swept_\w+-[^`]*[0-9a-f]{8}`", after_runs)


@pytest.mark.parametrize(
    ("key", "value", "words"),
    [
        ("bodies.ball.pos[2]", 2.0, "ball released at z = 2 m"),
        ("ball.vel[0]", -1.5, "ball vx = -1.5 m/s"),
        ("bodies.b.mass", 2.0, "b mass = 2 kg"),
        ("contact.solimp[0]", 0.9, "solimp[0] = 0.9"),
        ("options.timestep", 0.001, "options.timestep = 0.001"),
    ],
)
def test_parameter_words(key, value, words):
    assert parameter_words(key, value) == words


UNIT = re.compile(r"\((m|s|m/s|J|N|kg m/s|m; 0: at rest)\)|coefficient of restitution|e$|number")


@pytest.mark.slow
def test_every_figure_has_labelled_axes_with_units(record_spec, tmp_path, monkeypatch):
    """Axis labels read back from the figure objects as they are saved: each says what it
    shows and in which unit (or that it is a ratio such as e); study-drop's x axis is the drop
    height in m, not a spec path."""
    import impactlab.analyze.report.figures as figures

    seen: dict[str, list[tuple[str, str]]] = {}
    save = figures.save_figure

    def capture(fig, path, **kw):
        seen[path.name] = [
            (ax.get_xlabel(), ax.get_ylabel())
            for ax in fig.axes
            if ax.get_visible() and ax.has_data()
        ]
        return save(fig, path, **kw)

    monkeypatch.setattr(figures, "save_figure", capture)
    logs = record_spec("swept_drop", DROP) + record_spec("swept_collision", COLLISION)
    assert run_analysis(logs, tmp_path / "out").exit_code == 0
    assert "study-swept_drop.png" in seen and "restitution-vs-speed.png" in seen
    assert sum(len(axes) for axes in seen.values()) >= 8  # energy, decay, collision, studies
    for name, axes in seen.items():
        for xlabel, ylabel in axes:
            for label in (xlabel, ylabel):
                if label:
                    assert UNIT.search(label) or label.startswith("contact."), (name, label)
    (drop_axes,) = seen["study-swept_drop.png"]
    assert drop_axes[0].startswith("drop height") and drop_axes[0].endswith("(m)")
