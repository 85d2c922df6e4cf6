"""The report's opening: the rubric table and one short answer per handout step.

Each answer is the handout's question, one or two sentences with the key number read from the
tables (or the reason there is none), the one figure that shows it and a link to the detail.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import polars as pl

from impactlab.analyze.report import findings as F
from impactlab.text import file_part, md_code, md_link, md_text

RUBRIC = (
    ("Energy analysis", 25, "Step 1", "step-1-energy"),
    ("Restitution measurement", 25, "Step 2", "step-2-restitution"),
    ("Collision dynamics", 25, "Step 3", "step-3-collision"),
    ("Parameter study", 15, "Step 4", "step-4-parameter-studies"),
)

QUESTIONS = {
    "energy": "Is the total energy conserved during flight and lost during contact?",
    "restitution": "Is the coefficient of restitution constant across bounces, and does it "
    "depend on the drop height (impact speed)?",
    "collision": "Is momentum conserved in the two-ball collision, and does the kinetic energy "
    "lost match the analytic prediction for the measured e?",
    "study": "As the contact parameter moves towards an elastic contact, do the velocities "
    "after the collision approach the elastic answer?",
}


def _pick(paths: list[Path], prefer: str) -> Path | None:
    """The figure whose name contains `prefer`, else the first, else None."""
    return next((p for p in paths if prefer in p.name), paths[0] if paths else None)


@F.guard_line("Step 1")
def energy_line(runs: pl.DataFrame) -> str:
    """Step 1 in one or two sentences: the flight drift against the integrator's, and the share
    of the initial energy gone at the end (`findings` chooses the words)."""
    ground = runs.filter(pl.col("ground") & pl.col("energy_initial_J").is_not_null())
    if ground.is_empty():
        return (
            "Not answered: no run has a ground to fall onto, so there is no contact to lose energy."
        )
    kinds: list[str] = []
    odd: list[str] = []  # the first few runs whose drift is unexplained
    n_odd = 0
    worst_i, worst_drift = -1, -1.0
    for i, r in enumerate(ground.iter_rows(named=True)):  # one row at a time
        kind = F.drift_kind(r)
        kinds.append(kind)
        if kind != "none" and abs(r.get("flight_drift_J") or 0.0) > worst_drift:
            worst_i, worst_drift = i, abs(r.get("flight_drift_J") or 0.0)
        if kind == "unexplained":
            n_odd += 1
            if len(odd) < 4:
                odd.append(_who(r))
    if worst_i >= 0:
        worst = ground.row(worst_i, named=True)
        n_ok = sum(k in ("negligible", "integrator") for k in kinds)
        n_flown = sum(k != "none" for k in kinds)
        drift_words = (
            f"in {n_ok} of {n_flown} run(s) with a flight the energy is conserved in flight "
            f"up to the integrator's drift (at most {F.DRIFT_FACTOR:g} times m g^2 dt T / 2 for "
            "the semi-implicit integrators, none for RK4)"
            + (
                f"; not in {n_odd} ({', '.join(odd[:3])}{', ...' if n_odd > 3 else ''})"
                if n_odd
                else ""
            )
            + f". Largest drift, run {_who(worst)}: {F.drift_finding(worst)}"
        )
    else:
        drift_words = "no run has a flight phase to test conservation on"
    finals = ground["energy_final_J"] if "energy_final_J" in ground.columns else None
    start_end = zip(
        ground["energy_initial_J"].to_list(),
        finals.to_list() if finals is not None else [None] * ground.height,
        strict=True,
    )
    lost = [
        (energy_start, energy_start - energy_end)
        for energy_start, energy_end in start_end
        if F.defined(energy_start) and F.defined(energy_end)
    ]
    readable = [
        d / energy_start * 100
        for energy_start, d in lost
        if not F.negligible(energy_start) and abs(d / energy_start) <= F.PERCENT_MAX
    ]
    other = len(lost) - len(readable)
    if readable:
        lost_words = f"at the end {F.span(readable, '.1f', '%')} of the initial energy is gone"
        if min(readable) < 0:
            lost_words += " (negative: the run ends with more energy than it started with)"
        if other:
            lost_words += (
                f"; {other} run(s) start with zero or too little energy for a percentage "
                "(their change in J is in the detail)"
            )
    elif lost:
        lost_words = (
            f"the {len(lost)} run(s) start with zero or too little energy for a percentage of "
            f"it; their energy changes by {F.span([-d for _, d in lost], '.4g', 'J')}"
        )
    else:
        lost_words = "no run ends with a measurable energy"
    return f"Over {ground.height} run(s) with a ground, {drift_words}; {lost_words}." + rest_line(
        ground
    )


def _who(row: dict[str, Any]) -> str:
    return f'"{md_text(row.get("run") or row["run_id"])}"'


def rest_line(ground: pl.DataFrame) -> str:
    """Why runs that end at rest end early and slightly below zero energy ("" if none do)."""
    rest = ground.filter(pl.col("reason") == "bodies at rest")
    if rest.is_empty():
        return ""
    named = rest.filter(pl.col("experiment") == "free_fall")
    r = (named if named.height else rest).row(0, named=True)
    who = md_text(r.get("run") or r["run_id"])
    out = (
        f' {rest.height} run(s) stop once every body is at rest (stop rule `at_rest`): "{who}" '
        f"ends at {r['duration_s']:.3g} s (the handout runs 2 s; the rest would log a ball "
        "lying still)."
    )
    final = r["energy_final_J"]
    if final is not None and final < 0:
        out += (
            f" Its final energy is slightly negative ({final:.3g} J): the ball rests a fraction "
            "of a millimetre into MuJoCo's soft contact, below the surface where potential "
            "energy is zero."
        )
    return out


@F.guard_line("Step 2")
def restitution_line(
    runs: pl.DataFrame, bounces: pl.DataFrame, studies: dict[str, pl.DataFrame]
) -> str:
    """Step 2 in two sentences: the spread of e across bounces, e against drop height."""
    out = []
    if not bounces.is_empty() and "complete" in bounces.columns:
        done = bounces.filter(pl.col("complete") & pl.col("e_velocity").is_not_null())
        spread = (
            done.group_by("run_id", "body", "surface")
            .agg(pl.len().alias("n"), (pl.max("e_velocity") - pl.min("e_velocity")).alias("s"))
            .filter(pl.col("n") >= 2)
        )
        if spread.height:
            worst = float(spread.select(pl.col("s").max()).item())
            within = int((spread["s"] < F.E_CONSTANT_SPREAD).sum())
            pairs = f"{spread.height} body-surface pair(s) with two or more complete bounces"
            out.append(
                f"Across bounces e is constant: its spread (max - min) is at most {worst:.3f} "
                f"over {pairs}, below the {F.E_CONSTANT_SPREAD:g} threshold."
                if worst < F.E_CONSTANT_SPREAD
                else f"Across bounces e is not constant: its spread (max - min) reaches "
                f"{worst:.3f} over {pairs}, above the {F.E_CONSTANT_SPREAD:g} threshold; "
                f"{within} of them stay within it."
            )
        else:
            out.append("No run has two complete bounces, so constancy cannot be tested.")
    heights = []
    for name, study in studies.items():
        if "e_velocity_first" not in study.columns or "first_impact_speed_mps" not in study.columns:
            continue
        rows = study.filter(pl.col("e_velocity_first").is_not_null())
        speeds = F.span(study["first_impact_speed_mps"].to_list(), ".3g", "m/s")
        if rows.height and speeds:
            heights.append(
                f"{md_code(name)}: e = {F.span(rows['e_velocity_first'].to_list(), '.3f')} "
                f"for impacts at {speeds} ({rows.height} of {study.height} heights rebound)"
            )
    if heights:
        out.append("Against drop height: " + "; ".join(heights) + ".")
    return " ".join(out) or "Not answered: no run has a bounce."


@F.guard_line("Step 3")
def collision_line(collisions: pl.DataFrame, runs: pl.DataFrame | None = None) -> str:
    """Step 3 in two sentences: momentum change, measured and predicted energy loss."""
    if collisions.is_empty():
        return "Not answered: no run has two bodies that collide."
    done = collisions.filter(pl.col("complete"))
    if done.is_empty():
        why = md_text(collisions["note"][0] or "no complete collision")
        return f"Not answered: no collision separated ({why})."
    by_run = F.momentum_runs(runs, done)
    kinds = [F.momentum_kind(c, by_run.get(c["run_id"])) for c in done.iter_rows(named=True)]
    rels = [v for v in done["momentum_rel_change"].to_list() if F.defined(v)]
    if all(k == "conserved" for k in kinds):
        out = (
            f"Momentum is conserved in all {done.height} collision(s): its relative change is at "
            f"most {max(rels):.1g} (below {F.MOMENTUM_CONSERVED_REL:g}) and nothing else "
            "touched the pairs. "
        )
    else:
        odd = done.row(next(i for i, k in enumerate(kinds) if k != "conserved"), named=True)
        n = sum(k == "conserved" for k in kinds)
        words = F.momentum_finding(odd, by_run.get(odd["run_id"]))
        out = (
            f"Momentum is conserved in {n} of {done.height} collision(s); in run {_who(odd)} "
            f"({md_text(odd['body1'])}-{md_text(odd['body2'])}) {words}. "
        )
    r = done.row(0, named=True)
    before, after = r["ke_before_J"], r["ke_after_J"]
    if F.defined(before) and F.defined(after):
        out += (
            f"In run {_who(r)} the kinetic energy falls by {before - after:.4g} J "
            f"({before:.4g} J -> {after:.4g} J)"
        )
        e, predicted = r["e_velocity"], r["ke_loss_predicted_J"]
        if F.defined(e) and F.defined(predicted):
            out += f"; the 1D formula with the measured e = {e:.3f} predicts {predicted:.4g} J."
        else:
            out += f"; no 1D prediction ({md_text(r['note'] or 'e is not measured')})."
    return out


@F.guard_line("Step 4")
def study_line(studies: dict[str, pl.DataFrame], params: dict[str, list[str]]) -> str:
    """Step 4 in one or two sentences: per collision sweep, e's span and the elastic gap."""
    out = []
    for name, study in studies.items():
        if "e_collision" not in study.columns or not params.get(name):
            continue
        rows = study.filter(pl.col("e_collision").is_not_null())
        if rows.is_empty():
            continue
        el1 = rows["v1n_after_elastic_mps"][0]
        gap = F.elastic_gap(rows["v1n_after_mps"].to_list(), el1)
        elastic = (
            f"the closest v1' is {gap * 100:.0f} % of |v1'_elastic| = {abs(el1):.3f} m/s away "
            "from the elastic answer"
            if gap is not None
            else "the elastic answer is not defined for it (not a central impact)"
        )
        out.append(
            f"{md_code(name)} (sweeping {md_text(params[name][0])}): "
            f"e = {F.span(rows['e_collision'].to_list(), '.3f')}, {elastic}"
        )
    return ("; ".join(out) + ".") if out else "Not answered: no collision sweep."


def headline(
    *,
    out_dir: Path,
    runs: pl.DataFrame,
    bounces: pl.DataFrame,
    collisions: pl.DataFrame,
    studies: dict[str, pl.DataFrame],
    params: dict[str, list[str]],
    figures: dict[str, list[Path]],
) -> list[str]:
    """Markdown lines: the rubric table, then `## Answers` with one subsection per step."""
    lines = ["\n## Rubric\n", "| Rubric item | Points | Answered in |", "|---|---|---|"]
    for item, points, step, anchor in RUBRIC:
        lines.append(
            f"| {item} | {points} | [{step} answer](#{anchor}-answer), [detail](#{anchor}) |"
        )
    drawn = any(figures.values())
    lines.append(
        "| Visualisation | 10 | one figure per answer below; every figure in the detail "
        "sections and `figures/` |"
        if drawn
        else "| Visualisation | 10 | not answered: this analysis drew no figures (`--no-figures`) |"
    )
    study_figs = [
        p
        for name in studies
        if "e_collision" in studies[name].columns
        for p in figures.get("study", [])
        if p.stem == f"study-{file_part(name)}"
    ]
    steps = [
        (
            "Step 1: energy",
            "energy",
            energy_line(runs),
            _pick(figures.get("energy", []), "free_fall"),
        ),
        (
            "Step 2: restitution",
            "restitution",
            restitution_line(runs, bounces, studies),
            _pick(figures.get("restitution", []), "vs-speed"),
        ),
        (
            "Step 3: collision",
            "collision",
            collision_line(collisions, runs),
            _pick(figures.get("collision", []), "collision-collision-"),
        ),
        (
            "Step 4: parameter studies",
            "study",
            study_line(studies, params),
            _pick(study_figs, "restitution"),
        ),
    ]
    lines.append("\n## Answers\n")
    for (title, key, answer, figure), (_, _, _, anchor) in zip(steps, RUBRIC, strict=True):
        lines += [f"\n### {title} answer\n", f"**Question.** {QUESTIONS[key]}\n"]
        lines.append(f"**Answer.** {answer}\n")
        if figure is not None:
            lines.append(f"![{title}]({md_link(figure.relative_to(out_dir).as_posix())})\n")
        lines.append(f"Detail: [{title}](#{anchor}).\n")
    return lines
