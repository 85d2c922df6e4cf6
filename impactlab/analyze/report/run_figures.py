"""Each run's own figures (energy, first collision), their titles and labels."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from impactlab.analyze.measure.analysis import RunAnalysis
from impactlab.logs.labels import run_label
from impactlab.logs.metadata import GeomContact, PairTarget
from impactlab.text import file_part


def contact_words(targets: Sequence[PairTarget], shared: GeomContact | None) -> str:
    """What the contact is: the calibrated pairs' target e (one when they share it, else per
    pair; an e(v) by its ends), or else the solref/solimp every geom shares; "" when neither
    is known."""
    said = [_target_words(t) for t in targets]
    if len(set(said)) == 1:
        return f"restitution {said[0]}"
    if targets:
        return "restitution " + ", ".join(
            f"{t.pair} {w}" for t, w in zip(targets, said, strict=True)
        )
    if shared is not None:
        solref, solimp = (" ".join(f"{x:g}" for x in v) for v in (shared.solref, shared.solimp))
        return f"solref {solref}; solimp {solimp}"
    return ""


def _target_words(t: PairTarget) -> str:
    if t.curve_speed_mps and t.curve_e:
        ends = ((t.curve_e[i], t.curve_speed_mps[i]) for i in (0, -1))
        return "e(v) " + " to ".join(f"{e:g} at {v:g} m/s" for e, v in ends)
    return f"= {t.restitution:g}"


def run_title(a: RunAnalysis) -> str:
    """A figure title: the run's label, the contact, the timestep."""
    contact = contact_words(a.run.contact_targets, a.run.geom_contact)
    second = ", ".join([*([contact] if contact else []), f"dt = {a.run.timestep_s:g} s"])
    return f"{run_label(a.run.experiment, a.run.sweep)}\n{second}"


FIGURE_RUNS_PER_SWEEP = 6  # per-run figures for at most this many points of a sweep


def draws_own_figures(sweep_index: int, sweep_size: int) -> bool:
    """Whether a sweep point gets its own figures: all of a small sweep, else evenly spread."""
    if sweep_size <= FIGURE_RUNS_PER_SWEEP:
        return True
    chosen = np.linspace(0, sweep_size - 1, FIGURE_RUNS_PER_SWEEP).round().astype(int)
    return sweep_index in set(chosen.tolist())


def run_figures(a: RunAnalysis, fig_dir: Path) -> list[tuple[str, Path]]:
    """Draw one run's own figures (energy, first collision); returns (kind, path) in order.

    In a sweep of many runs only `FIGURE_RUNS_PER_SWEEP` evenly spread points get them;
    the sweep's summary figures cover every run. A figure whose inputs did not change since
    the last analysis into the same folder is copied (`figure_cache.draw_all`).
    """
    if not draws_own_figures(*a.run.sweep_point):
        return []
    from impactlab.analyze.report.figure_cache import draw_all, figure_job

    contacts = a.phases.filter(pl.col("kind") == "contact")
    title = run_title(a)
    jobs: list[tuple[str, str, tuple[Any, ...]]] = []  # kind, drawing function, its data
    if a.ground is not None and a.ground.surfaces and a.energy.height:
        jobs.append(("energy", "energy_figure", (a.energy, contacts)))
    impacts = a.collisions.filter(pl.col("px_before_Ns").is_not_null())  # a state before
    for row in impacts.head(1).iter_rows(named=True):
        jobs.append(("collision", "collision_figure", (a.states, row, contacts)))
    paths = draw_all(
        [
            figure_job(fig_dir / f"{kind}-{file_part(a.run.run_id)}.png", name, *data, title=title)
            for kind, name, data in jobs
        ]
    )
    return [(kind, path) for (kind, _, _), path in zip(jobs, paths, strict=True)]
