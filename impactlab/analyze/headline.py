"""The report's opening: the rubric table and one short answer per handout step.

Each answer is the handout's question, one or two sentences with the key number read from the
tables (or the reason there is none), the one figure that shows it and a link to the detail.
"""

from __future__ import annotations

from pathlib import Path

import polars as pl

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


def energy_line(runs: pl.DataFrame) -> str:
    """Step 1 in one sentence: the largest flight drift and the range of energy lost."""
    ground = runs.filter(pl.col("ground") & pl.col("energy_initial_J").is_not_null())
    if ground.is_empty():
        return (
            "Not answered: no run has a ground to fall onto, so there is no contact to lose energy."
        )
    drift = ground["flight_drift_max_rel"].drop_nulls()
    lost = ground["energy_loss_frac"].drop_nulls()
    drift_words = (
        f"during flight the total energy drifts by at most {drift.max() * 100:.3g} % of the "
        "initial energy (the semi-implicit Euler drift, not a physical loss)"
        if drift.len()
        else "no run has a flight phase to test conservation on"
    )
    lost_words = (
        f"the contacts remove the rest: {lost.min() * 100:.1f}-{lost.max() * 100:.1f} % of the "
        "initial energy is gone at the end"
        if lost.len()
        else "no run ends with a measurable loss"
    )
    return f"Over {ground.height} run(s) with a ground, {drift_words}; {lost_words}." + rest_line(
        ground
    )


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


def restitution_line(runs: pl.DataFrame, bounces: pl.DataFrame, studies: dict) -> str:
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
            out.append(
                f"Across bounces e is constant to within {spread['s'].max():.3f} (largest "
                f"spread max - min over {spread.height} run(s) with two or more complete bounces)."
            )
        else:
            out.append("No run has two complete bounces, so constancy cannot be tested.")
    heights = []
    for name, study in studies.items():
        if "e_velocity_first" not in study.columns or "first_impact_speed_mps" not in study.columns:
            continue
        rows = study.filter(pl.col("e_velocity_first").is_not_null())
        speeds = study["first_impact_speed_mps"].drop_nulls()
        if rows.height and speeds.len():
            heights.append(
                f"{md_code(name)}: e = {rows['e_velocity_first'].min():.3f}-"
                f"{rows['e_velocity_first'].max():.3f} for impacts at "
                f"{speeds.min():.3g}-{speeds.max():.3g} m/s ({rows.height} of {study.height} "
                "heights rebound)"
            )
    if heights:
        out.append("Against drop height: " + "; ".join(heights) + ".")
    return " ".join(out) or "Not answered: no run has a bounce."


def collision_line(collisions: pl.DataFrame) -> str:
    """Step 3 in two sentences: momentum change, measured and predicted energy loss."""
    if collisions.is_empty():
        return "Not answered: no run has two bodies that collide."
    done = collisions.filter(pl.col("complete"))
    if done.is_empty():
        return f"Not answered: no collision separated ({md_text(collisions['note'][0])})."
    r = done.row(0, named=True)
    loss = r["ke_before_J"] - r["ke_after_J"]
    who = md_text(r.get("run") or r["run_id"])
    return (
        f"Momentum is conserved: its relative change is at most "
        f"{done['momentum_rel_change'].max():.1g} over {done.height} collision(s). "
        f'In run "{who}" the '
        f"kinetic energy falls by {loss:.4g} J ({r['ke_before_J']:.4g} J -> "
        f"{r['ke_after_J']:.4g} J); the 1D formula with the measured e = {r['e_measured']:.3f} "
        f"predicts {r['ke_loss_predicted_J']:.4g} J."
    )


def study_line(studies: dict, params: dict[str, list[str]]) -> str:
    """Step 4 in one or two sentences: per collision sweep, e's span and the elastic gap."""
    out = []
    for name, study in studies.items():
        if "e_collision" not in study.columns or not params.get(name):
            continue
        rows = study.filter(pl.col("e_collision").is_not_null())
        if rows.is_empty():
            continue
        el1 = rows["v1n_after_elastic_mps"][0]
        gap = ((rows["v1n_after_mps"] - el1).abs() / abs(el1 or 1.0)).min()
        out.append(
            f"{md_code(name)} (sweeping {md_text(params[name][0])}): "
            f"e = {rows['e_collision'].min():.3f}-"
            f"{rows['e_collision'].max():.3f}, the closest v1' is {gap * 100:.0f} % of "
            f"|v1'_elastic| = {abs(el1):.3f} m/s away from the elastic answer"
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
            collision_line(collisions),
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
