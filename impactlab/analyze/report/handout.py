"""The handout's scripts as written, beside the corrected runs: what each gives and why."""

from __future__ import annotations

import polars as pl

from impactlab.analyze.report import findings as F
from impactlab.analyze.report.blocks import Block, Column, Heading, Paragraph, Table, span
from impactlab.analyze.report.context import Tables
from impactlab.show import number

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
        "restitution (MuJoCo has no restitution parameter): e stays near 0.15 and |v1'_elastic| "
        "is never approached. The corrected sweep asks for restitution = 0.5 ... 0.99, which "
        "impactlab turns into a calibrated solref.",
    ),
)
"""(step, the handout's experiment, the corrected one, what went wrong)."""


def measured(experiment: str, t: Tables) -> str | None:
    """What the experiment's runs gave, in a few words with their numbers (None: no runs)."""
    ids = t.runs.filter(pl.col("experiment") == experiment)["run_id"]
    if ids.is_empty():
        return None
    col = t.collisions.filter(pl.col("run_id").is_in(ids.implode()))
    if col.height:
        done = col.filter(pl.col("complete") & pl.col("e_velocity").is_not_null())
        if done.is_empty():
            row = col.row(0, named=True)
            after = [
                f"{name}' = {number(row[c])} m/s"
                for name, c in (("v1", "v1n_after_mps"), ("v2", "v2n_after_mps"))
                if F.defined(row[c])
            ]
            return f"no collision: {row['note']}" + (f"; {', '.join(after)}" if after else "")
        momentum, _ = F.momentum_words(done, t.runs)
        words = f"e = {span(done['e_velocity'].to_list())}; {momentum}"
        gap = F.elastic_gap(done["v1n_after_mps"].to_list(), done["v1n_after_elastic_mps"][0])
        if done.height > 1 and gap is not None:
            words += f"; closest v1' {number(gap * 100, 2)} % from the elastic answer"
        return words
    e = t.runs.filter(pl.col("experiment") == experiment)["e_velocity_first"].drop_nulls()
    if e.is_empty():
        return f"no rebound in {ids.len()} run(s)"
    return f"e = {span(e.to_list())} at the first impact ({e.len()} of {ids.len()} runs rebound)"


def as_written(t: Tables) -> list[Block]:
    """The section on the handout's scripts as written ([]: none of them was run)."""
    rows = []
    for step, written, corrected, why in PAIRS:
        before, after = measured(written, t), measured(corrected, t)
        if before is not None and after is not None:
            rows.append((step, f"{written}: {before}", f"{corrected}: {after}", why))
    if not rows:
        return []
    frame = pl.DataFrame(rows, schema=["step", "written", "corrected", "why"], orient="row")
    frame = frame.with_columns(pl.Series("note", [str(i) for i in range(1, len(rows) + 1)]))
    cols = (
        Column("step", "Step"),
        Column("written", "As written"),
        Column("corrected", "Corrected"),
        Column("note", "Why: note"),
    )
    return [
        Heading("The handout as written"),
        Paragraph(("The handout's scripts run as written, beside the corrected runs:",)),
        Table(frame, cols, notes=tuple(r[3] for r in rows)),
    ]
