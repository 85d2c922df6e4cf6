"""Answers to the handout's questions, worded from the computed tables (no fixed conclusions).

Each function takes the tables and returns Markdown sentences; the thresholds that choose the
words are named constants in `findings`, so the words follow the numbers.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import polars as pl

from impactlab.analyze.report import findings as F
from impactlab.text import md_code, md_text

E_CONSTANT_SPREAD = F.E_CONSTANT_SPREAD
APPROACH_FRACTION = F.APPROACH_FRACTION


def _f(x: float | None, fmt: str = ".3g") -> str:
    return format(x, fmt) if F.defined(x) else "n/a"


def _who(row: dict[str, Any]) -> str:
    """The run's readable label when the table has one (`labels.with_labels`), else its id."""
    return md_text(row["run"]) if row.get("run") else md_code(row["run_id"])


@F.guard_lines("the energy answer")
def energy_answer(runs: pl.DataFrame) -> Iterator[str]:
    """Is energy conserved in flight and lost at contacts? One sentence per run with a
    ground, its words chosen by `findings` from its numbers and its integrator."""
    rows = runs.filter(pl.col("ground")).iter_rows(named=True)  # one row at a time
    return F.each((r for r in rows if r["energy_initial_J"] is not None), _energy_sentence)


def _spread(values: pl.Series) -> float:
    """max - min of a column (nulls left out)."""
    return float(values.to_frame().select(pl.all().max() - pl.all().min()).item())


def _energy_sentence(r: dict[str, Any]) -> str:
    energy_start, energy_end = r["energy_initial_J"], r["energy_final_J"]
    contacts = r["contact_loss_sum_J"]
    if not (F.defined(energy_start) and F.defined(energy_end)):
        end = "the energy at the end is not measured"
    elif energy_end > energy_start and not F.negligible(energy_end - energy_start, energy_start):
        end = f"the energy gained is {F.of_initial(energy_end - energy_start, energy_start)}"
    else:
        end = f"the energy gone is {F.of_initial(energy_start - energy_end, energy_start)}"
    removed = ""
    if F.defined(contacts):
        removed = f"the contacts {'add' if contacts < 0 else 'remove'} {abs(contacts):.4g} J; "
    return f"{_who(r)}: {F.drift_finding(r)}; {removed}at the end ({_f(r['duration_s'])} s) {end}."


@F.guard_lines("the answer on e across bounces")
def constancy_answer(runs: pl.DataFrame, bounces: pl.DataFrame) -> Iterator[str]:
    """Is e constant across bounces? Asked of each body on each surface of each run: bodies
    with different contacts are never put in one answer."""
    if bounces.is_empty() or "surface" not in bounces.columns:
        return
    keys = ["run_id", "body", "surface"]
    e = pl.col("e_velocity").cast(pl.Float64)
    # each pair's first row (its name), complete bounces' e in order and its contacts, in
    # columns: a few values per pair, never a Python object per run
    per_pair = bounces.group_by(keys, maintain_order=True).agg(
        pl.col("run").first() if "run" in bounces.columns else pl.lit(None).alias("run"),
        e.filter(pl.col("complete") & e.is_not_null() & e.is_not_nan()).alias("es"),
        pl.len().alias("n_contacts"),
    )
    text = pl.col("reason").is_not_null() & (pl.col("reason") != "")
    said = pl.col("outcome").is_not_null() & (pl.col("outcome") != "")
    reasons = runs.select(
        "run_id",
        pl.when(text)
        .then(pl.col("reason"))
        .when(said)
        .then(pl.col("outcome"))
        .otherwise(pl.lit("reason not recorded"))
        .alias("why"),
    ).unique("run_id", keep="last", maintain_order=True)
    pairs = (
        bounces.filter(pl.col("bounce").is_not_null())
        .select(keys)
        .unique(maintain_order=True)
        .join(per_pair, on=keys, how="left", maintain_order="left")
        .join(reasons, on="run_id", how="left", maintain_order="left")
    )
    for row in pairs.iter_rows(named=True):
        es: list[float] = row["es"]
        who = f"{_who(row)}, {md_text(row['body'])} on {md_text(row['surface'])}"
        if len(es) >= 2:
            spread = float(max(es) - min(es))
            vals = ", ".join(f"{e:.3f}" for e in es)
            yield (
                f"{who}: across its {len(es)} complete bounces ({vals}) e is "
                f"{F.spread_finding(spread)}."
            )
        else:
            yield (
                f"{who}: {len(es)} complete bounce(s) "
                f"({', '.join(f'{e:.3f}' for e in es) or 'none'}), so constancy across bounces "
                "cannot be tested: the log ends "
                f"({md_text(row['why'] or 'reason not recorded')}) "
                f"after {row['n_contacts']} contact(s) with an impact, the last one without a "
                "flight after it."
            )


@F.guard_lines("the answer on e against drop height")
def height_answer(studies: dict[str, pl.DataFrame]) -> list[str]:
    """Does e depend on the drop height (impact speed)?"""
    out = []
    for name, study in studies.items():
        if "first_impact_speed_mps" not in study.columns:
            continue
        rows = study.sort("first_impact_speed_mps")
        if "e_velocity_first" not in rows.columns:  # no run of the study has a full bounce
            rows = rows.with_columns(pl.lit(None, dtype=pl.Float64).alias("e_velocity_first"))
        parts = []
        for r in rows.iter_rows(named=True):
            e, h, v = r["e_velocity_first"], r["drop_height_m"], r["first_impact_speed_mps"]
            parts.append(
                (f"{h:.3g} m drop" if F.defined(h) else "drop height not measured")
                + (f", {v:.3g} m/s impact: " if F.defined(v) else ", no impact speed: ")
                + ("no rebound (the ball stays on the plane)" if e is None else f"e = {e:.3f}")
            )
        es = rows.filter(pl.col("e_velocity_first").is_not_null())
        if es.height >= 2:
            lo, hi = es["e_velocity_first"][0], es["e_velocity_first"][-1]
            trend = (
                "rises with the impact speed"
                if hi > lo + E_CONSTANT_SPREAD
                else "falls with the impact speed"
                if hi < lo - E_CONSTANT_SPREAD
                else f"does not depend on the impact speed (within {E_CONSTANT_SPREAD})"
            )
            verdict = f"e {trend} ({lo:.3f} -> {hi:.3f})"
        elif es.height == 1:
            verdict = "only one drop height rebounds at all, so e depends on the impact speed"
        else:
            verdict = "no drop height rebounds"
        out.append(f"{md_code(name)}: {'; '.join(parts)}. So {verdict}.")
    return out


@F.guard_lines("the collision answer")
def collision_answer(collisions: pl.DataFrame, runs: pl.DataFrame | None = None) -> Iterator[str]:
    """Is momentum conserved in the collisions, how much kinetic energy is lost? The
    momentum's words come from `findings.momentum_finding` (its change and what else acted
    on the pair, with the run's row from `runs`)."""
    by_run = F.momentum_runs(runs, collisions)
    return F.each(
        collisions.iter_rows(named=True), lambda r: _collision_sentence(r, by_run.get(r["run_id"]))
    )


def _pair(r: dict[str, Any]) -> str:
    return f"{md_text(r['body1'])}-{md_text(r['body2'])}"


def _collision_sentence(r: dict[str, Any], run: dict[str, Any] | None) -> str:
    if not r["complete"]:
        why = r["note"] or "incomplete (no state after the contact, or the bodies were not closing)"
        return f"{_who(r)} ({_pair(r)}): {md_text(why)}."
    out = f"{_who(r)} ({_pair(r)}): {F.momentum_finding(r, run)}"
    before, after, frac = r["ke_before_J"], r["ke_after_J"], r["ke_loss_frac"]
    if F.defined(before) and F.defined(after):
        out += f"; the kinetic energy falls from {before:.4g} J to {after:.4g} J"
        out += f" ({frac * 100:.1f} % lost)" if F.defined(frac) else ""
    out += "."
    e, predicted = r["e_velocity"], r["ke_loss_predicted_J"]
    if F.defined(e):
        out += f" Measured e = {e:.3f}"
        out += (
            f"; the 1D formula predicts a loss of {predicted:.4g} J for it."
            if F.defined(predicted)
            else f"; no 1D prediction ({md_text(r['note'] or 'the impact is not central')})."
        )
    names = ("v1n_after_mps", "v2n_after_mps")
    if all(F.defined(r[c]) for c in names):
        out += f" After: v1' = {r['v1n_after_mps']:.3f}, v2' = {r['v2n_after_mps']:.3f} m/s"
        elastic = ("v1n_after_elastic_mps", "v2n_after_elastic_mps", "v_after_inelastic_mps")
        if all(F.defined(r[c]) for c in elastic):
            out += (
                f" (elastic: {r['v1n_after_elastic_mps']:.3f}, "
                f"{r['v2n_after_elastic_mps']:.3f}; perfectly inelastic: "
                f"{r['v_after_inelastic_mps']:.3f} m/s)"
            )
        out += "."
    return out


@F.guard_lines("the parameter study answer")
def study_answer(studies: dict[str, pl.DataFrame], params: dict[str, list[str]]) -> list[str]:
    """What does each collision parameter study show?"""
    out = []
    for name, study in studies.items():
        if "e_collision" not in study.columns or not params.get(name):
            continue
        param = params[name][0]
        rows = study.filter(pl.col("e_collision").is_not_null()).sort(param)
        if rows.is_empty():
            out.append(f"{md_code(name)}: no run of the sweep has a collision.")
            continue
        es = rows["e_collision"]
        el1, el2 = rows["v1n_after_elastic_mps"][0], rows["v2n_after_elastic_mps"][0]
        gap = F.elastic_gap(rows["v1n_after_mps"].to_list(), el1)
        spread = _spread(es)
        vals = ", ".join(
            f"{p:g}: e = {e:.3f} (v1' = {_f(a, '.3f')}, v2' = {_f(b, '.3f')})"
            for p, e, a, b in rows.select(
                param, "e_collision", "v1n_after_mps", "v2n_after_mps"
            ).iter_rows()
        )
        knob = (
            f"e spans only {spread:.3f} over the sweep (below {F.E_KNOB_SPREAD:g}: essentially "
            "independent of the knob)"
            if spread < F.E_KNOB_SPREAD
            else f"e follows the knob, spanning {spread:.3f} over the sweep"
        )
        if gap is None or not F.defined(el2):
            elastic = "; the elastic answer is not defined for it (not a central impact)."
        else:
            word = "approached" if gap < F.APPROACH_FRACTION else "not approached"
            elastic = (
                f"; the elastic answer v1' = {el1:.3f}, v2' = {el2:.3f} m/s is {word} (closest "
                f"v1' is {gap * 100:.0f} % of |v1'_elastic| away, threshold "
                f"{F.APPROACH_FRACTION * 100:.0f} %)."
            )
        out.append(f"{md_code(name)} over {md_text(param)} = {vals}. {knob}{elastic}")
    return out
