"""The handout's four questions, one function each: the answer's blocks (a first sentence that
answers with its number, the evidence, one figure); that sentence is also the conclusion's."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import polars as pl

from impactlab.analyze.measure.phases import WORK_COLUMNS
from impactlab.analyze.report import findings as F
from impactlab.analyze.report.blocks import (
    Block,
    Bullets,
    Column,
    Link,
    Paragraph,
    Span,
    Strong,
    Table,
    footnoted,
    percent,
    quantity,
    span,
)
from impactlab.analyze.report.context import COLUMNS, Tables, columns
from impactlab.analyze.report.standards import balls, drop_tests
from impactlab.physics import collision_after
from impactlab.show import number
from impactlab.text import file_part

MAIN_ROWS = 12
"""Rows a table of the answers shows; all of them are in the appendix."""
APPENDIX = "report-appendix.md"
IN_APPENDIX = Link("the appendix", APPENDIX)


@dataclass
class Answer:
    """A question's answer: its lead (whose first span, in bold, answers the question: the
    conclusion says it again) and the evidence."""

    lead: list[Span]
    evidence: list[Block] = field(default_factory=list)
    whole: Table | None = None
    """The answer's table with every run and the checks beside it, for the appendix."""

    @property
    def finding(self) -> str:
        first = self.lead[0]
        return first if isinstance(first, str) else first.text


def not_answered(why: str) -> Answer:
    return Answer([Strong(f"Not answered: {why}.")])


def _who(row: dict[str, Any]) -> str:
    return str(row.get("run") or row["run_id"])


def _targets(t: Tables) -> pl.Expr:
    """Each run's target e (the calibrated pairs'), as text; "" when not calibrated."""
    words = {r: ", ".join(f"{e:g}" for e in b.targets) for r, b in t.briefs.items()}
    return pl.col("run_id").replace_strict(words, default="", return_dtype=pl.String)


FORCES = [c for c in WORK_COLUMNS if not c.startswith("work_contact")]
"""The budget's works besides the contacts' (a sentence names each by its column's header)."""


def energy(t: Tables) -> Answer:
    """Step 1: is the energy conserved in flight and lost at the contacts? Every number is
    the budget's: the work of each kind of force, and the integrator's residual."""
    known = t.runs.filter(pl.col("energy_initial_J").is_not_null())
    if "ground" in known.columns:  # falls first: the question is the drop's
        known = known.sort("ground", descending=True, maintain_order=True)
    if known.is_empty():
        return not_answered("nothing moves in any run" if t.still else "no run's energy is known")
    booked = [c for c in ("work_contact_normal_J", "work_contact_friction_J") if c in known.columns]
    contacts = (
        pl.sum_horizontal(booked)
        if booked
        else -pl.col("contact_loss_sum_J")
        if "contact_loss_sum_J" in known.columns
        else pl.lit(None, pl.Float64)
    )
    frame = known.with_columns(contacts.alias("contacts_J"))
    rows = list(frame.iter_rows(named=True))

    def acting(r: dict[str, Any], column: str) -> bool:
        return F.defined(r.get(column)) and not F.negligible(r[column], r["energy_initial_J"])

    forces = [c for c in FORCES if c in frame.columns and any(acting(r, c) for r in rows)]
    kinds = F.each(rows, F.drift_kind)
    flown = [r for r, k in zip(rows, kinds, strict=True) if k != "none"]
    odd = [r for r, k in zip(rows, kinds, strict=True) if k == "unexplained"]
    forced = [r for r in flown if any(acting(r, c) for c in forces)]
    lost = [
        F.share(-r["contacts_J"], r["energy_initial_J"]) for r in rows if acting(r, "contacts_J")
    ]
    removed = span([x * 100 for x in lost if x is not None], "%")
    at_contacts = (
        f"the contacts remove {removed} of it"
        if removed
        else "the contacts do work"
        if lost
        else "no contact does work"
    )
    others = [
        f"{COLUMNS[c].header.lower()} {span([r[c] for r in rows if acting(r, c)], 'J')}"
        for c in forces
    ]
    also = f"; other forces work too ({', '.join(others)})" if others else ""
    if not flown:
        lead = f"Not answered for the flight: no run has one; {at_contacts}{also}."
    elif odd or forced:
        who = (odd or forced)[0]
        what = (
            f"changes by more than the integrator explains ({quantity(F.drift(who), 'J')})"
            if odd
            else "is also changed by other forces"
        )
        lead = (
            f"Not in every run: in {len(odd) or len(forced)} of {len(flown)} runs with a "
            f"flight the energy in flight {what} ({_who(who)}); {at_contacts}{also}."
        )
    else:
        worst = max(flown, key=lambda r: abs(F.drift(r) / r["energy_initial_J"]))
        rel = percent(abs(F.drift(worst) / worst["energy_initial_J"]))
        lead = (
            f"Yes: in flight only the integrator changes the energy (at most {rel} of it), "
            f"and {at_contacts}{also}."
        )
    notes = F.each(rows, lambda r: F.drift_finding(r) if F.drift_kind(r) == "unexplained" else "")
    table, footnotes = footnoted(
        frame.with_columns(
            pl.Series("flight", [F.DRIFT_WORDS.get(k, k) for k in kinds], dtype=pl.String),
            pl.Series("note", notes, dtype=pl.String),
        ),
        "note",
    )
    cols = (
        *columns(table, "run", "energy_initial_J"),
        Column("contacts_J", "Contacts' work", "J"),
        *columns(table, *forces, "residual_J", "energy_final_J"),
        *columns(table, "flight_drift_J", "flight_drift_predicted_J"),
        Column("flight", "In flight"),
        Column("note", "Note"),
    )
    said = [
        "Energy change = the work of each kind of force + the integrator's residual, "
        "summed over every simulated step."
    ]
    if frame["flight_drift_predicted_J"].drop_nulls().len():
        said.append(
            "A semi-implicit integrator (Euler, as in the handout) loses m g² dt T / 2 in a "
            "free flight of T seconds: that is the drift predicted beside each run's below."
        )
    evidence: list[Block] = [Bullets(tuple((s,) for s in (*said, *F.at_rest(frame))))]
    evidence.append(Table(table, cols, footnotes, IN_APPENDIX, MAIN_ROWS))
    checks = columns(table, "contact_loss_sum_J", "mujoco_diff_max_J")
    whole = Table(table, (*cols[:-1], *checks, cols[-1]), footnotes, "runs.parquet")
    order = ["n_bounces_complete", "drop_height_m"]
    best = frame.sort(order, descending=True, nulls_last=True).row(0, named=True)
    caption = f"{_who(best)}: the ball's height and energy against time; contacts shaded."
    evidence += t.figures_of("energy", {f"energy-{file_part(best['run_id'])}": caption})
    return Answer([Strong(lead)], evidence, whole)


def restitution(t: Tables) -> Answer:
    """Step 2: is e constant across bounces, and does it depend on the drop height?"""
    if t.bounces.is_empty():
        return not_answered("no run has a bounce")
    done = t.bounces.filter(pl.col("complete") & pl.col("e_velocity").is_not_null())
    if "target_e" not in done.columns:  # a table from elsewhere: no calibrated pair known
        done = done.with_columns(target_e=pl.lit(None, pl.Float64))
    if done.is_empty():
        hits = t.bounces.filter(pl.col("v_in_mps").is_not_null())
        return not_answered(
            f"no rebound: {hits.height} impact(s) in {hits['run_id'].n_unique()} run(s), each "
            "body still on its surface at the end"
            if hits.height
            else "no run has a bounce"
        )
    e = pl.col("e_velocity")
    # a calibrated pair is judged in its speed range (its bounces with a target e)
    pair = ("run_id", "run", "body", "surface")
    calibrated = pl.col("target_e").is_not_null().any().over(pair)
    outside = done.filter(calibrated & pl.col("target_e").is_null())
    spread = (
        done.filter(~calibrated | pl.col("target_e").is_not_null())
        .group_by(pair, maintain_order=True)
        .agg(pl.len().alias("n"), (e.max() - e.min()).alias("s"))
        .filter(pl.col("n") >= 2)
    )
    limit = f"{F.E_CONSTANT_SPREAD:g}"
    curved = [k for k, b in t.briefs.items() if b.curves]  # e varies with v as asked
    varied = spread.filter(pl.col("run_id").is_in(curved))
    spread = spread.filter(~pl.col("run_id").is_in(curved))
    if spread.is_empty() and varied.is_empty():
        across = "Constancy across bounces is not tested (no run has two complete bounces)"
    elif spread.is_empty():
        across = "No, e is not constant across bounces, as its target e(v) asks"
    else:
        worst = spread.sort("s", descending=True).row(0, named=True)
        most = number(worst["s"], 2)
        if worst["s"] < F.E_CONSTANT_SPREAD:
            across = f"Yes, e is constant across bounces (spread at most {most}, below {limit})"
        else:
            within = int((spread["s"] < F.E_CONSTANT_SPREAD).sum())
            across = (
                f"No, e is not constant across bounces in every drop (spread up to {most} in "
                f"{worst['run']}, above {limit}; {within} of {spread.height} within it)"
            )
    if outside.height and spread.height:
        speeds = span((-outside["v_in_mps"]).to_list(), "m/s")
        es = span(outside["e_velocity"].to_list())
        across += f" in the calibrated speed range (outside it: e {es} at {speeds})"
    if varied.height:
        names = sorted({t.briefs[k].experiment for k in varied["run_id"]})
        where = f"{', '.join(names)}: spread up to {number(varied['s'].max(), 2)}"
        across += f", except as a target e(v) asks ({where})" if spread.height else f" ({where})"
    heights = [(name, _height_words(s)) for name, s in t.studies.items()]
    heights = [h for h in heights if h[1]]
    against = " and ".join(f"{words} for {n}" for n, words in heights)
    lead = across + (f"; against the drop height it {against}." if against else ".")
    studies = [t.studies[n].sort("first_impact_speed_mps") for n, _ in heights]
    table = pl.concat(studies, how="diagonal_relaxed") if studies else pl.DataFrame()
    said = []
    if studies:
        table = table.with_columns(_targets(t).alias("target"))
        table = table.join(_first_targets(t), on="run_id", how="left", maintain_order="left")
        table = table.with_columns(
            pl.coalesce(pl.col("target_first"), pl.col("target")).alias("target")
        )
        aimed = table.filter(pl.col("target") != "")
        off = (pl.col("e_velocity_first") - pl.col("target").cast(pl.Float64, strict=False)).abs()
        most_off = aimed.select(off.max()).item() if aimed.height else None
        if F.defined(most_off):
            said.append(
                f"Where the contact was calibrated to a target e, the first bounce's e is within "
                f"{number(most_off, 2)} of it: an independent check, the target being set before "
                "the run."
            )
    said += [_curve_words(t, name, rows) for name, rows in _curved(t, done).items()]
    said += _drop_test_words(t)
    apex = done.filter(pl.col("e_apex").is_not_null()) if "e_apex" in done.columns else done.clear()
    if apex.height:
        gap = apex.select((pl.col("e_apex") - e).abs().max()).item()
        said.append(
            f"e from the apex heights, √(h after / h before), agrees with e from the velocities "
            f"to {number(gap, 2)}, as it must: the apexes are refined ballistically from the same "
            "flights, so this checks the bookkeeping, not the measurement."
        )
    evidence: list[Block] = [Bullets(tuple((s,) for s in said))] if said else []
    if studies:
        cols = columns(table, "run", "drop_height_m", "first_impact_speed_mps")
        cols += columns(table, "e_velocity_first", "e_apex_mean")
        cols += (Column("target", "Target e"),)
        evidence.append(Table(table, cols, source=IN_APPENDIX, limit=MAIN_ROWS))
    caption = "e against impact speed: every bounce and every collision, one colour per experiment."
    evidence += t.figures_of("restitution", {"restitution-vs-speed": caption})
    return Answer([Strong(lead)], evidence)


def _first_targets(t: Tables) -> pl.DataFrame:
    """run_id -> the target e (text) of the first bounce of each run whose contact has an
    e(v) curve: the curve at that impact's speed ("" outside the curve's speeds)."""
    curved = [r for r, b in t.briefs.items() if b.curves]
    first = (
        t.bounces.filter(pl.col("run_id").is_in(curved))
        .sort("impact_t_s")
        .group_by("run_id", maintain_order=True)
        .agg(pl.col("target_e").first())
        if "target_e" in t.bounces.columns
        else pl.DataFrame(schema={"run_id": pl.String, "target_e": pl.Float64})
    )
    words = [number(e) if e is not None else "" for e in first["target_e"]]
    return pl.DataFrame(
        {"run_id": first["run_id"], "target_first": words},
        schema={"run_id": pl.String, "target_first": pl.String},
    )


def _curved(t: Tables, done: pl.DataFrame) -> dict[str, pl.DataFrame]:
    """experiment -> its complete bounces with a target, of each experiment whose contact
    has a target e(v) curve."""
    names = {b.experiment for b in t.briefs.values() if b.curves}
    runs = {r: b.experiment for r, b in t.briefs.items() if b.experiment in names}
    aimed = done.filter(pl.col("run_id").is_in(list(runs)) & pl.col("target_e").is_not_null())
    aimed = aimed.with_columns(
        pl.col("run_id").replace_strict(runs, return_dtype=pl.String).alias("experiment")
    )
    return {n: aimed.filter(pl.col("experiment") == n) for n in sorted(names)}


def _curve_words(t: Tables, name: str, rows: pl.DataFrame) -> str:
    """How e follows an experiment's target e(v): how much it falls (or rises) over the
    impact speeds measured, and its worst distance from the target."""
    if rows.is_empty():
        return f"{name}'s contact has a target e(v), but no bounce was inside its speeds."
    rows = rows.with_columns((-pl.col("v_in_mps")).alias("v")).sort("v")
    slow, fast = rows.row(0, named=True), rows.row(-1, named=True)
    off = rows.select((pl.col("e_velocity") - pl.col("target_e")).abs().max()).item()
    follows = (
        f"within {number(off, 2)} of the target at its speed"
        if off <= F.E_TARGET_TOLERANCE
        else f"up to {number(off, 2)} off the target at its speed, more than "
        f"{F.E_TARGET_TOLERANCE:g}"
    )
    return (
        f"{name}: the contact's target e {_change(fast['target_e'] - slow['target_e'])} over "
        f"these speeds, and the measured e {_change(fast['e_velocity'] - slow['e_velocity'])}"
        f", from {number(slow['e_velocity'])} at "
        f"{quantity(slow['v'], 'm/s')} to {number(fast['e_velocity'])} at "
        f"{quantity(fast['v'], 'm/s')}; its {rows.height} bounces are {follows}."
    )


def _change(d: float) -> str:
    """How e changes by `d` from the slowest impact to the fastest."""
    if abs(d) < F.E_CONSTANT_SPREAD:
        return f"stays within {number(abs(d), 2)} of one value"
    return f"{'falls' if d < 0 else 'rises'} by {number(abs(d), 2)}"


def _drop_test_words(t: Tables) -> list[str]:
    """Each drop test a run is (a rule's ball dropped from its height): pass or fail, by the
    measured e of that impact."""
    found = drop_tests(t.bounces, balls(t.briefs.values()))
    out = []
    for r in found.iter_rows(named=True):
        verdict = "passes" if r["passed"] else "fails"
        out.append(
            f"{_who({'run_id': r['run_id'], 'run': t.briefs[r['run_id']].label})} is the "
            f"{r['test']} drop test ({quantity(r['drop_m'], 'm')}, impact at "
            f"{quantity(r['speed_mps'], 'm/s')}): measured e = {number(r['e'])}, the rule asks "
            f"{number(r['lo'])} to {number(r['hi'])} (no air in MuJoCo: e = √(rebound / drop)), "
            f"so it {verdict}."
        )
    return out


def _height_words(study: pl.DataFrame) -> str:
    """How e depends on the drop height in one drop study, with its numbers; "" for a study
    that is not of drops."""
    if not {"e_velocity_first", "first_impact_speed_mps"} <= set(study.columns):
        return ""
    study = study.sort("first_impact_speed_mps")
    es = study.filter(pl.col("e_velocity_first").is_not_null())["e_velocity_first"]
    if es.len() >= 2:  # the speeds are in the table below the answer
        if es.max() - es.min() < F.E_CONSTANT_SPREAD:  # type: ignore[operator]
            return f"does not depend on it ({span(es.to_list())})"
        trend = "rises" if es[-1] > es[0] else "falls"
        return f"{trend} with it ({number(es[0])} to {number(es[-1])})"
    if es.len() == 1:
        return f"depends on it (only one of {study.height} drops rebounds, e = {number(es[0])})"
    return f"cannot be measured (none of {study.height} drops rebounds)"


def collision(t: Tables) -> Answer:
    """Step 3: is momentum conserved, and does the kinetic energy lost match the prediction?"""
    if t.collisions.is_empty():
        return not_answered("no run has two bodies that collide")
    done = t.collisions.filter(pl.col("complete"))
    if done.is_empty():
        why = t.collisions["note"][0] or "no complete collision"
        return not_answered(f"no collision separated ({why})")
    momentum, odd = F.momentum_words(done, t.runs)
    momentum = momentum[0].upper() + momentum[1:] if odd else f"Yes, {momentum}"
    alone = done.join(t.runs.select("run_id", "experiment"), on="run_id")
    alone = alone.filter(pl.len().over("experiment") == 1)
    main = (alone if alone.height else done).row(0, named=True)
    keys = ("ke_before_J", "ke_after_J", "e_velocity", "ke_loss_predicted_J")
    lead: list[Span] = [Strong(momentum + ".")]
    if all(F.defined(main.get(k)) for k in keys):
        before, after, e, predicted = (float(main[k]) for k in keys)
        lead = [
            Strong(
                f"{momentum}, and the kinetic energy lost in {_who(main)}, "
                f"{quantity(before - after, 'J')} of {quantity(before, 'J')}, is what the 1D "
                f"formula gives for the measured e = {number(e)}, but that check is circular."
            ),
            f" The formula's {quantity(predicted, 'J')} follows from e, and e is measured from "
            "the same velocities, so the two agree for any central impact that conserves "
            "momentum; the independent checks are the analytic outcomes below and, in Step 4, "
            "the target e.",
        ]
    evidence: list[Block] = [Bullets(tuple((s,) for s in odd[:3]))] if odd else []
    evidence += _outcomes(main)
    caption = f"{_who(main)}: positions, velocities and momentum along the line of centres."
    evidence += t.figures_of("collision", {f"collision-{file_part(main['run_id'])}": caption})
    return Answer(lead, evidence)


def _outcomes(c: dict[str, Any]) -> list[Block]:
    """The measured outcome of a collision beside the elastic and perfectly inelastic ones."""
    needed = (
        "m1_kg",
        "m2_kg",
        "v1n_before_mps",
        "v2n_before_mps",
        "v1n_after_mps",
        "v2n_after_mps",
    )
    if not all(F.defined(c.get(k)) for k in needed) or not c["m1_kg"] + c["m2_kg"]:
        return []
    m1, m2, v1, v2 = (float(c[k]) for k in needed[:4])
    outcomes = [("measured", c["e_velocity"], c["v1n_after_mps"], c["v2n_after_mps"])]
    for name, e in (("elastic", 1.0), ("perfectly inelastic", 0.0)):
        outcomes.append((name, e, *collision_after(m1, m2, v1, v2, e)))
    ke = 0.5 * m1 * v1**2 + 0.5 * m2 * v2**2
    frame = pl.DataFrame(
        [(*o, ke - 0.5 * m1 * o[2] ** 2 - 0.5 * m2 * o[3] ** 2) for o in outcomes],
        schema=["outcome", "e", "v1", "v2", "lost"],
        orient="row",
    )
    cols = (
        Column("outcome", "Outcome"),
        Column("e", "e"),
        Column("v1", "v1 after", "m/s"),
        Column("v2", "v2 after", "m/s"),
        Column("lost", "Kinetic energy lost", "J"),
    )
    intro = (
        f"{_who(c)}: {quantity(m1, 'kg', None)} at {quantity(v1, 'm/s', None)} against "
        f"{quantity(m2, 'kg', None)} at {quantity(v2, 'm/s', None)}, measured beside the "
        "handout's analytic outcomes (velocities along the line of centres):"
    )
    return [Paragraph((intro,)), Table(frame, cols)]


def study(t: Tables) -> Answer:
    """Step 4: as the contact moves towards elastic, do the velocities approach the elastic
    answer?"""
    sweeps = []
    for name, s in t.studies.items():
        if "e_collision" not in s.columns or not t.params.get(name):
            continue
        rows = s.filter(pl.col("e_collision").is_not_null())
        if rows.height:
            el1 = rows["v1n_after_elastic_mps"][0]
            sweeps.append((name, rows, el1, F.elastic_gap(rows["v1n_after_mps"].to_list(), el1)))
    if not sweeps:
        return not_answered("no collision sweep")
    near = [s for s in sweeps if s[3] is not None and s[3] < F.APPROACH_FRACTION]
    far = [s for s in sweeps if s not in near]

    def said(name: str, rows: pl.DataFrame, el1: Any, gap: float | None) -> str:
        es = rows["e_collision"].to_list()
        knob = max(es) - min(es) >= F.E_KNOB_SPREAD
        moves = f"as e goes from {span(es)}" if knob else f"e stays at {span(es)}"
        elastic = quantity(el1, "m/s")
        if gap is None:
            return f"{name}, where {moves}: the elastic answer is not defined (an eccentric impact)"
        if gap < F.APPROACH_FRACTION:
            return f"{name}: {moves}, v1' comes within {percent(gap, 2)} of the elastic {elastic}"
        far = f"v1' stays {percent(gap, 2)} or more from the elastic {elastic}"
        return f"{name}, where {moves} and {far}"

    if near:
        lead = "Yes, with " + "; ".join(said(*s) for s in near)
        lead += ("; not with " + "; ".join(said(*s) for s in far)) if far else ""
    else:
        lead = "No: " + "; ".join(said(*s) for s in sweeps)
    elastic = pl.col("v1n_after_elastic_mps")
    gap = (pl.col("v1n_after_mps") - elastic).abs() / elastic.abs() * 100
    table = pl.concat([s[1] for s in sweeps], how="diagonal_relaxed")
    table = table.with_columns(_targets(t).alias("target"), gap.alias("gap"))
    cols = (
        *columns(table, "run", "e_collision"),
        Column("target", "Target e"),
        *columns(table, "v1n_after_mps", "v2n_after_mps"),
        Column("gap", "v1 from elastic", "%"),
    )
    first = sweeps[0][1].row(0, named=True)
    swept = "; ".join(f"{n} sweeps {t.params[n][0]}" for n, *_ in sweeps)
    more = (
        f" The elastic answer (e = 1) is v1' = {quantity(first['v1n_after_elastic_mps'], 'm/s')}, "
        f"v2' = {quantity(first['v2n_after_elastic_mps'], 'm/s')} ({swept})."
    )
    pick = (near or sweeps)[0][0]
    caption = f"{pick}: velocities after against e, on the analytic curves; e against the sweep."
    evidence: list[Block] = [Table(table, cols, source=IN_APPENDIX, limit=MAIN_ROWS)]
    evidence += t.figures_of("study", {f"study-{file_part(pick)}": caption})
    return Answer([Strong(lead + "."), more], evidence)
