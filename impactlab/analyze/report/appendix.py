"""The report's appendix: every table and figure, the method, the files."""

from __future__ import annotations

import polars as pl

from impactlab.analyze.measure.phases import WORK_COLUMNS
from impactlab.analyze.report import findings as F
from impactlab.analyze.report.blocks import (
    Block,
    Bullets,
    Column,
    Contents,
    Document,
    Heading,
    Link,
    Paragraph,
    Table,
    footnoted,
)
from impactlab.analyze.report.context import Tables, columns, repeat_notes
from impactlab.text import file_part

METHOD = (
    "Ground and heights come from the model: a body's height above a surface is its lowest "
    "point's (a sphere: centre minus radius above a plane). Apexes are the highest centre of "
    "each flight, refined ballistically.",
    "Contacts come from the contact channel: consecutive logged steps with a contact of a geom "
    "pair form one contact. A release slower than 5 g x (time between logged steps), a flight "
    "of fewer than 10 logged steps, is merged with the next contact: a resting, sliding or "
    "rolling contact that flickers is one contact, not bounces.",
    "Velocities in and out are those of the contact point along the contact normal at the "
    "moments the surfaces meet and part (the free flight extrapolated ballistically from the "
    "last logged step before and the first after), so e and the impact speed do not depend on "
    "the logging rate. e = -v_out / v_in; for two bodies, of their relative normal velocity.",
    "Energy: kinetic (translational and rotational) plus potential m g h, zero for a body "
    "resting on the surface it lands on. A contact's loss is the energy before it minus the "
    "energy after; MuJoCo's own energy sensors are compared after the same shift of zero.",
    "Collisions: the momentum change is |p' - p| / (|m1 v1| + |m2 v2|); the analytic outcomes "
    "use the 1D formulas with the measured e, e = 1 (elastic) and e = 0 (perfectly inelastic).",
)
FILES = (
    "runs.parquet: one row per run (parameters, state of the log, results)",
    "bounces.parquet, collisions.parquet, energy.parquet, phases.parquet: the tables above, whole",
    "summary.json: the runs, the studies and the answers",
    "figures/: every figure",
)


def appendix(t: Tables, budget: Table | None = None) -> Document:
    """The appendix document (`budget`: Step 1's table whole, `questions.Answer.whole`)."""
    doc = Document("Impact lab: appendix")
    doc.blocks += [
        Paragraph(
            (
                "The details behind ",
                Link("the report", "report.md"),
                ": every table whole, every figure.",
            )
        ),
        Contents(),
        *_runs(t),
        *_energy(t, budget),
        *_bounces(t),
        *_collisions(t),
        *_studies(t),
        Heading("Method"),
        Bullets(tuple((s,) for s in (*METHOD, F.method_sentence(), t.energy_note) if s)),
        Heading("Files"),
        Bullets(tuple((s,) for s in FILES)),
    ]
    return doc


def _run_captions(t: Tables, kind: str) -> dict[str, str]:
    """figure stem -> the run's label, for the runs reported."""
    return {
        f"{kind}-{file_part(r)}": label for r, label in t.runs.select("run_id", "run").iter_rows()
    }


def _runs(t: Tables) -> list[Block]:
    same = pl.col("run_id").replace_strict(
        repeat_notes(t), default=pl.col("note"), return_dtype=pl.String
    )
    frame, notes = footnoted(t.all_runs.with_columns(same.alias("note")), "note")
    cols = columns(
        frame,
        "run",
        "run_id",
        "outcome",
        "reason",
        "duration_s",
        "n_bounces",
        "n_collisions",
        "note",
    )
    return [Heading("Runs"), Table(frame, cols, notes, "runs.parquet")]


def _energy(t: Tables, budget: Table | None) -> list[Block]:
    """Every run's energy budget (Step 1's table, whole) and each contact's."""
    out: list[Block] = [Heading("Energy")]
    if budget is not None:
        out.append(budget)
    booked = [
        c for c in WORK_COLUMNS if c in t.runs.columns and (t.runs[c].fill_null(0) != 0).any()
    ]
    contacts = (
        t.phases.filter(pl.col("kind") == "contact")
        if "kind" in t.phases.columns
        else t.phases.clear()
    )
    if contacts.height:
        out += [
            Paragraph(("The energy change over each contact, and the work that made it:",)),
            Table(
                contacts,
                columns(contacts, "run", "start_t_s", "end_t_s", "change_J", *booked, "residual_J"),
                source="phases.parquet",
            ),
        ]
    if len(out) == 1:
        return []
    return out + t.figures_of("energy", _run_captions(t, "energy"))


def _bounces(t: Tables) -> list[Block]:
    if t.bounces.is_empty():
        return []
    several = [c for c in ("body", "surface") if t.bounces[c].n_unique() > 1]
    frame, notes = footnoted(t.bounces, "note")
    cols = columns(
        frame,
        "run",
        *several,
        "bounce",
        "impact_t_s",
        "v_in_mps",
        "v_out_mps",
        "e_velocity",
        "e_apex",
        "apex_before_m",
        "apex_m",
        "peak_force_N",
        "impulse_Ns",
        "max_penetration_m",
        "note",
    )
    decay = {
        f"bounce-decay-{file_part(e)}": f"Bounce height decay: {e}"
        for e in t.runs["experiment"].unique()
    }
    return [
        Heading("Bounces"),
        Paragraph(
            ("Speeds are of the contact point along the normal; heights of the lowest point.",)
        ),
        Table(frame, cols, notes, "bounces.parquet"),
        *t.figures_of("decay", decay),
        *t.figures_of("restitution", {"restitution-vs-speed": "e against impact speed"}),
    ]


def _collisions(t: Tables) -> list[Block]:
    if t.collisions.is_empty():
        return []
    frame, notes = footnoted(t.collisions, "note")
    cols = columns(
        frame,
        "run",
        "e_velocity",
        "v1n_before_mps",
        "v2n_before_mps",
        "v1n_after_mps",
        "v2n_after_mps",
        "momentum_rel_change",
        "ke_before_J",
        "ke_after_J",
        "ke_loss_predicted_J",
        "note",
    )
    return [
        Heading("Collisions"),
        Paragraph(("Velocities of the contact points along the contact normal:",)),
        Table(frame, cols, notes, "collisions.parquet"),
        *t.figures_of("collision", _run_captions(t, "collision")),
    ]


def _studies(t: Tables) -> list[Block]:
    out: list[Block] = []
    for name, study in t.studies.items():
        params = t.params.get(name, [])
        results = [
            c for c in study.columns if c not in ("run_id", "run", "partial", "note", *params)
        ]
        cols = (
            *columns(study, "run"),
            *(Column(p, p, digits=None) for p in params),
            *columns(study, *results),
        )
        out += [Heading(f"Parameter study: {name}", 3), Table(study, cols, source="summary.json")]
    if not out:
        return []
    studies = {f"study-{file_part(n)}": f"Parameter study: {n}" for n in t.studies}
    return [Heading("Parameter studies"), *out, *t.figures_of("study", studies)]
