"""Each run's own figures (energy, first collision), their titles and labels."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl

from impactlab.analyze.analysis import RunAnalysis


def run_title(a: RunAnalysis) -> str:
    """A figure title: experiment, sweep point, contact parameters and timestep."""
    sweep = ", ".join(f"{k.split('.')[-1]} = {v}" for k, v in a.run.sweep.items())
    contact = a.run.spec.get("contact", {})
    parts = [a.run.experiment + (f" ({sweep})" if sweep else "")]
    if contact:
        parts.append(f"solref {contact.get('solref')}, solimp {contact.get('solimp')}")
    parts.append(f"dt = {a.run.timestep_s:g} s")
    return "\n".join([parts[0], ", ".join(parts[1:])])


def run_label(a: RunAnalysis) -> str:
    """A short legend label: the sweep point, else the run id."""
    sweep = ", ".join(f"{k.split('.')[-1]} = {v}" for k, v in a.run.sweep.items())
    return sweep or a.run.run_id


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
    the sweep's summary figures cover every run.
    """
    made: list[tuple[str, Path]] = []
    if not draws_own_figures(*a.run.sweep_point):
        return made
    from impactlab.analyze import figures  # matplotlib: only when figures are drawn

    contacts = a.phases.filter(pl.col("kind") == "contact")
    if a.ground is not None and a.ground.surfaces and a.energy.height:
        path = fig_dir / f"energy-{a.run.run_id}.png"
        made.append(
            ("energy", figures.energy_figure(a.energy, contacts, title=run_title(a), path=path))
        )
    for row in a.collisions.head(1).iter_rows(named=True):
        path = fig_dir / f"collision-{a.run.run_id}.png"
        made.append(
            (
                "collision",
                figures.collision_figure(a.states, row, contacts, title=run_title(a), path=path),
            )
        )
    return made
