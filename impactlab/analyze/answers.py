"""Answers to the handout's questions, worded from the computed tables (no fixed conclusions).

Each function takes the tables and returns Markdown sentences; thresholds used for wording are
named constants so the words follow the numbers.
"""

from __future__ import annotations

import polars as pl

from impactlab.text import md_code, md_text

E_CONSTANT_SPREAD = 0.02
"""Spread (max - min) of e below which e is called constant."""

APPROACH_FRACTION = 0.1
"""A sweep approaches the elastic answer when its best run is within this fraction of it."""


def _f(x: float | None, fmt: str = ".3g") -> str:
    return "n/a" if x is None else format(x, fmt)


def _who(row: dict) -> str:
    """The run's readable label when the table has one (`labels.with_labels`), else its id."""
    return md_text(row["run"]) if row.get("run") else md_code(row["run_id"])


def energy_answer(runs: pl.DataFrame) -> list[str]:
    """Is energy conserved in flight and lost at contacts?"""
    out = []
    for r in runs.filter(pl.col("ground")).iter_rows(named=True):
        if r["energy_initial_J"] is None:
            continue
        drift = r["flight_drift_max_rel"]
        out.append(
            f"{_who(r)}: flight phases keep the total energy to "
            f"{_f(drift and drift * 100)} % "
            f"of the initial {r['energy_initial_J']:.4g} J (largest flight drift "
            f"{_f(r['flight_drift_max_J'])} J, the semi-implicit Euler drift m g^2 dt T / 2); the "
            f"contacts remove {r['contact_loss_sum_J']:.4g} J, i.e. "
            f"{_f(r['energy_loss_frac'] and r['energy_loss_frac'] * 100, '.1f')} % of it is gone "
            f"at the end ({r['duration_s']:.3g} s)."
        )
    return out


def constancy_answer(runs: pl.DataFrame, bounces: pl.DataFrame) -> list[str]:
    """Is e constant across bounces? Asked of each body on each surface of each run: bodies
    with different contacts are never put in one answer."""
    out = []
    if bounces.is_empty() or "surface" not in bounces.columns:
        return out
    pairs = bounces.filter(pl.col("bounce").is_not_null()).select("run_id", "body", "surface")
    reasons = {
        run_id: reason or outcome
        for run_id, reason, outcome in runs.select("run_id", "reason", "outcome").iter_rows()
    }
    for run_id, body, surface in pairs.unique(maintain_order=True).iter_rows():
        mine = bounces.filter(
            (pl.col("run_id") == run_id) & (pl.col("body") == body) & (pl.col("surface") == surface)
        )
        es = mine.filter(pl.col("complete"))["e_velocity"].drop_nulls()
        who = f"{_who(mine.row(0, named=True))}, {md_text(body)} on {md_text(surface)}"
        if es.len() >= 2:
            spread = float(es.max() - es.min())
            word = "constant" if spread < E_CONSTANT_SPREAD else "not constant"
            vals = ", ".join(f"{e:.3f}" for e in es)
            out.append(
                f"{who}: e is {word} across its {es.len()} complete bounces "
                f"({vals}; spread {spread:.3f})."
            )
        else:
            out.append(
                f"{who}: {es.len()} complete bounce(s) "
                f"({', '.join(f'{e:.3f}' for e in es) or 'none'}), so constancy across bounces "
                f"cannot be tested: the log ends ({md_text(reasons.get(run_id) or 'n/a')}) after "
                f"{mine.height} contact(s) with an impact, the last one without a flight after it."
            )
    return out


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
            e = r["e_velocity_first"]
            parts.append(
                f"{_f(r['drop_height_m'])} m drop, {_f(r['first_impact_speed_mps'])} m/s impact: "
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


def collision_answer(collisions: pl.DataFrame) -> list[str]:
    """Is momentum conserved in the collisions, how much kinetic energy is lost?"""
    out = []
    for r in collisions.iter_rows(named=True):
        if not r["complete"]:
            pair = f"{md_text(r['body1'])}-{md_text(r['body2'])}"
            out.append(f"{_who(r)} ({pair}): {md_text(r['note'])}.")
            continue
        out.append(
            f"{_who(r)}: momentum changes by {r['momentum_rel_change']:.2g} (relative), i.e. "
            f"it is conserved; the kinetic energy falls from {r['ke_before_J']:.4g} J to "
            f"{r['ke_after_J']:.4g} J ({r['ke_loss_frac'] * 100:.1f} % lost). Measured e = "
            f"{r['e_measured']:.3f}; the 1D formula predicts a loss of "
            f"{r['ke_loss_predicted_J']:.4g} J for it. After: v1' = {r['v1n_after_mps']:.3f}, "
            f"v2' = {r['v2n_after_mps']:.3f} m/s (elastic: {r['v1n_after_elastic_mps']:.3f}, "
            f"{r['v2n_after_elastic_mps']:.3f}; perfectly inelastic: "
            f"{r['v_after_inelastic_mps']:.3f} m/s)."
        )
    return out


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
        gap = ((rows["v1n_after_mps"] - el1).abs() / abs(el1 or 1.0)).to_list()
        approached = min(gap) < APPROACH_FRACTION
        spread = float(es.max() - es.min())
        vals = ", ".join(
            f"{p:g}: e = {e:.3f} (v1' = {a:.3f}, v2' = {b:.3f})"
            for p, e, a, b in rows.select(
                param, "e_collision", "v1n_after_mps", "v2n_after_mps"
            ).iter_rows()
        )
        out.append(
            f"{md_code(name)} over {md_text(param)} = {vals}. "
            + (
                f"e spans only {spread:.3f} over the sweep (essentially independent of the knob)"
                if spread < 0.05
                else f"e follows the knob, spanning {spread:.3f} over the sweep"
            )
            + f"; the elastic answer v1' = {el1:.3f}, v2' = {el2:.3f} m/s is "
            + ("approached" if approached else "not approached")
            + f" (closest v1' is {min(gap) * 100:.0f} % of |v1'_elastic| away)."
        )
    return out
