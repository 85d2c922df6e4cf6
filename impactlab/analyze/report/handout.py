"""The handout's scripts as written, beside the corrected runs: what each gives and why.

The lab records the handout's own experiments next to the corrected ones (`drop` with the
handout's contact beside `drop_restitution`, `collision_as_written` stopped at the handout's
0.5 s beside `collision`, the handout's `collision_sweep` over solimp[0] beside
`collision_sweep_restitution`). Every number here is read from the analysis tables of those
runs; a row whose runs were not analyzed is left out.
"""

from __future__ import annotations

import polars as pl

from impactlab.analyze.report import findings as F
from impactlab.text import md_text

PAIRS = (
    (
        "Steps 1-2: drops",
        "drop",
        "drop_restitution",
        "The handout's contact (solref = [0.02, 1]) is critically damped, so the ball barely "
        "rebounds; its script also finds bounces with a 0.1 m/s velocity threshold and measures "
        "heights from the ball's centre, so it detects no bounce from 1 m and reports the resting "
        "centre height (the radius) as a bounce height. Here bounces come from the contact and "
        "heights from the ball's lowest point, and the corrected contact is designed for "
        "restitution = 0.8.",
    ),
    (
        "Step 3: collision",
        "collision_as_written",
        "collision",
        "The balls start with their surfaces 1.8 m apart, closing at 3 m/s, so they meet at "
        "0.6 s; the handout's 5,000 steps of 0.1 ms end at 0.5 s, so its 'after' velocities are "
        "the initial ones. The corrected run stops once the balls have collided and separated.",
    ),
    (
        "Step 4: parameter study",
        "collision_sweep",
        "collision_sweep_restitution",
        "The handout sweeps solimp[0], the constraint's impedance, which does not set "
        "restitution (MuJoCo has no restitution parameter): e stays near 0.15 and the elastic "
        "answer is never approached. The corrected sweep asks for restitution = 0.5 ... 0.99, "
        "which impactlab turns into a calibrated solref.",
    ),
)


def _span(values: pl.Series, digits: int = 3) -> str:
    return F.span(values.to_list(), f".{digits}f") or "not measured"


@F.guard_line("this experiment's result")
def measured(experiment: str, runs: pl.DataFrame, collisions: pl.DataFrame) -> str | None:
    """What the experiment's runs gave, in a few words with their numbers (None: no runs)."""
    ids = runs.filter(pl.col("experiment") == experiment)["run_id"]
    if ids.is_empty():
        return None
    col = collisions.filter(pl.col("run_id").is_in(ids.implode()))
    if col.height:
        done = col.filter(pl.col("complete") & pl.col("e_velocity").is_not_null())
        if done.is_empty():
            row = col.row(0, named=True)
            after = [
                f"{name}' = {row[c]:.3g} m/s"
                for name, c in (("v1", "v1n_after_mps"), ("v2", "v2n_after_mps"))
                if F.defined(row[c])
            ]
            return f"no collision: {md_text(row['note'])}" + (
                f"; {', '.join(after)}" if after else ""
            )
        by_run = F.momentum_runs(runs, done)
        kinds = [F.momentum_kind(c, by_run.get(c["run_id"])) for c in done.iter_rows(named=True)]
        rels = done["momentum_rel_change"].drop_nulls()
        top = rels.to_frame().max().item()
        momentum = (
            f"momentum kept to {top:.1g} (relative)"
            if all(k == "conserved" for k in kinds)
            else f"momentum changes by up to {top:.2g} (relative)"
            if rels.len()
            else "momentum change not measured"
        )
        words = f"e = {_span(done['e_velocity'])} over {done.height} collision(s), {momentum}"
        if done.height > 1:  # a sweep: how close it comes to the elastic answer
            el1 = done["v1n_after_elastic_mps"][0]
            gap = F.elastic_gap(done["v1n_after_mps"].to_list(), el1)
            if gap is not None:
                words += (
                    f"; the closest v1' is {gap * 100:.0f} % of |v1'_elastic| = {abs(el1):.3f} "
                    "m/s from the elastic answer"
                )
        return words
    mine = runs.filter(pl.col("experiment") == experiment)
    e = mine["e_velocity_first"].drop_nulls()
    if e.is_empty():
        return f"no rebound in {mine.height} run(s)"
    return f"e = {_span(e)} at the first impact ({e.len()} of {mine.height} run(s) rebound)"


def as_written_section(runs: pl.DataFrame, collisions: pl.DataFrame) -> list[str]:
    """Markdown lines: the handout's scripts as written beside the corrected runs ([]: none)."""
    rows = []
    for step, written, corrected, why in PAIRS:
        before = measured(written, runs, collisions)
        after = measured(corrected, runs, collisions)
        if before is None or after is None:
            continue
        rows.append(f"| {step} | `{written}`: {before} | `{corrected}`: {after} | {why} |")
    if not rows:
        return []
    return [
        "\n## The handout as written\n",
        "The handout's scripts, run as written, next to the corrected runs (measured here):\n",
        "| Step | As written | Corrected | What went wrong |",
        "|---|---|---|---|",
        *rows,
        "",
    ]
