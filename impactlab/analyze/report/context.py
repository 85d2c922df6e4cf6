"""What the report is built from: the analysis tables, each run once, with readable labels."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from impactlab.analyze.measure.analysis import RunAnalysis
from impactlab.analyze.report.blocks import Column, Figure
from impactlab.analyze.report.run_figures import contact_words
from impactlab.logs.format import NOTHING_MOVES
from impactlab.logs.labels import run_label, run_labels
from impactlab.show import number

Curve = tuple[tuple[float, ...], tuple[float, ...]]
"""A target e(v): its points' normal impact speeds (m/s, ascending) and e."""


@dataclass(frozen=True)
class RunBrief:
    """What the report and the summary figures need of a run beyond the tables (a few
    strings and numbers from its metadata, whatever its length)."""

    run_id: str
    experiment: str
    label: str
    grounded: bool
    targets: tuple[float, ...]
    masses: tuple[float, ...]
    bodies: str
    contact: str
    gravity_mps2: float | None
    curves: tuple[Curve, ...] = ()
    """The target e(v) curves of its calibrated pairs (`targets`: the constant ones)."""
    radii: tuple[float | None, ...] = ()
    """Each body's radius in m, as `masses` (None: not one sphere)."""


def brief(a: RunAnalysis) -> RunBrief:
    """The run's `RunBrief`."""
    info, targets = a.run.body_info.values(), a.run.contact_targets
    kinds: dict[str, list[str]] = {}  # bodies alike, named together
    for b in info:
        size = f", r = {number(b.radius, None)} m" if b.radius else ""
        kinds.setdefault(f"{number(b.mass, None)} kg{size}", []).append(b.name)
    bodies = "; ".join(f"{', '.join(names)}: {kind}" for kind, names in kinds.items())
    bodies = bodies or NOTHING_MOVES
    try:
        gravity: float | None = float(np.linalg.norm(a.run.gravity))
    except Exception:
        gravity = None
    return RunBrief(
        run_id=a.run.run_id,
        experiment=a.run.experiment,
        label=run_label(a.run.experiment, a.run.sweep),
        grounded=a.ground is not None and bool(a.ground.surfaces),
        targets=tuple(sorted({t.restitution for t in targets if t.curve_e is None})),
        masses=tuple(b.mass for b in info),
        bodies=bodies,
        contact=contact_words(a.run.contact_targets, a.run.geom_contact),
        gravity_mps2=gravity,
        curves=tuple(
            dict.fromkeys(
                (t.curve_speed_mps, t.curve_e) for t in targets if t.curve_speed_mps and t.curve_e
            )
        ),
        radii=tuple(b.radius for b in info),
    )


COLUMNS = {
    name: Column(name, header, unit)
    for name, header, unit in (
        ("run", "Run", ""),
        ("run_id", "Run id (log)", ""),
        ("experiment", "Experiment", ""),
        ("outcome", "Outcome", ""),
        ("reason", "Stopped because", ""),
        ("duration_s", "Duration", "s"),
        ("n_bounces", "Bounces", ""),
        ("n_bounces_complete", "Complete bounces", ""),
        ("n_collisions", "Collisions", ""),
        ("energy_initial_J", "Initial energy", "J"),
        ("energy_final_J", "Final energy", "J"),
        ("contact_loss_sum_J", "Lost at contacts", "J"),
        ("flight_drift_J", "Largest flight drift", "J"),
        ("flight_drift_predicted_J", "Predicted drift", "J"),
        ("mujoco_diff_max_J", "MuJoCo's energy - ours, max", "J"),
        ("drop_height_m", "Drop height", "m"),
        ("first_impact_speed_mps", "Impact speed", "m/s"),
        ("e_velocity_first", "e, first bounce", ""),
        ("e_apex_mean", "mean e from apexes", ""),
        ("body", "Body", ""),
        ("surface", "Surface", ""),
        ("bounce", "Bounce", ""),
        ("impact_t_s", "Impact at", "s"),
        ("v_in_mps", "Speed in", "m/s"),
        ("v_out_mps", "Speed out", "m/s"),
        ("e_velocity", "e", ""),
        ("e_apex", "e from apexes", ""),
        ("apex_before_m", "Apex before", "m"),
        ("apex_m", "Apex after", "m"),
        ("peak_force_N", "Peak force", "N"),
        ("impulse_Ns", "Impulse", "N s"),
        ("max_penetration_m", "Penetration", "m"),
        ("start_t_s", "From", "s"),
        ("end_t_s", "To", "s"),
        ("change_J", "Energy change", "J"),
        ("work_contact_normal_J", "Contact normal force", "J"),
        ("work_contact_friction_J", "Friction", "J"),
        ("work_springs_J", "Springs", "J"),
        ("work_damping_J", "Joint damping", "J"),
        ("work_limits_J", "Joint limits", "J"),
        ("work_equality_J", "Equality constraints", "J"),
        ("work_friction_loss_J", "Friction loss", "J"),
        ("work_actuators_J", "Actuators", "J"),
        ("work_fluid_J", "Fluid forces", "J"),
        ("work_gravity_compensation_J", "Gravity compensation", "J"),
        ("work_solver_J", "Unconverged solver", "J"),
        ("residual_J", "Integrator's residual", "J"),
        ("bodies", "Bodies", ""),
        ("e_collision", "e", ""),
        ("v1n_before_mps", "v1 before", "m/s"),
        ("v2n_before_mps", "v2 before", "m/s"),
        ("v1n_after_mps", "v1 after", "m/s"),
        ("v2n_after_mps", "v2 after", "m/s"),
        ("v1n_after_elastic_mps", "v1 elastic", "m/s"),
        ("v2n_after_elastic_mps", "v2 elastic", "m/s"),
        ("momentum_rel_change", "Momentum change (relative)", ""),
        ("ke_before_J", "KE before", "J"),
        ("ke_after_J", "KE after", "J"),
        ("ke_loss_predicted_J", "KE loss, 1D formula", "J"),
        ("collision_ke_loss_frac", "KE lost", "fraction"),
        ("e_velocity_mean", "e, mean", ""),
        ("energy_loss_frac", "Energy lost", "fraction"),
        ("note", "Note", ""),
    )
}
"""Each table column the report shows, by its name in the tables: its header and unit."""


def columns(frame: pl.DataFrame, *names: str) -> tuple[Column, ...]:
    """The report's columns of those `names` the frame has (an unknown name as itself)."""
    return tuple(COLUMNS.get(n, Column(n, n)) for n in names if n in frame.columns)


@dataclass
class Tables:
    """The analysis' tables as the report reads them: each run once (`same`), with its
    readable label (column `run`), and what the metadata adds (`briefs`)."""

    runs: pl.DataFrame
    bounces: pl.DataFrame
    collisions: pl.DataFrame
    phases: pl.DataFrame
    studies: dict[str, pl.DataFrame]
    params: dict[str, list[str]]
    briefs: dict[str, RunBrief] = field(default_factory=dict)
    figures: dict[str, list[Path]] = field(default_factory=dict)
    failed: list[tuple[str, str]] = field(default_factory=list)
    energy_note: str = ""
    same: dict[str, str] = field(default_factory=dict)
    """Each run left out -> the run it repeats (the same physics, the same numbers)."""
    figures_asked: bool = True
    """Whether figures were asked for (`--no-figures` is False)."""
    all_runs: pl.DataFrame = field(default_factory=pl.DataFrame)
    """The runs table with every run, labelled (`runs` has each run once)."""

    @property
    def still(self) -> bool:
        """Whether nothing moves in any run (every body of every model welded to the world)."""
        bodies = self.runs.get_column("n_bodies", default=None)
        return bodies is not None and not bodies.is_empty() and bodies.max() == 0

    def figures_of(self, kind: str, captions: dict[str, str]) -> list[Figure]:
        """The figures of `kind` drawn that `captions` names (by their file's stem), captioned."""
        return [
            Figure(p, captions[p.stem]) for p in self.figures.get(kind, []) if p.stem in captions
        ]


IDENTITY_IGNORES = ("run_id", "experiment", "description", "file", "sweep", "note")
MEASURED = ("energy_initial_J", "first_impact_speed_mps", "e_collision", "v1n_before_mps")


def repeated_runs(runs: pl.DataFrame, params: dict[str, list[str]]) -> dict[str, str]:
    """Runs of different experiments that are the same run (every setting and result in the
    runs table equal to 12 significant digits, something measured): each later one -> the
    one kept, a run of the experiment with the most runs (a sweep point over a single run)."""
    swept = {p for ps in params.values() for p in ps}
    keys = [c for c in runs.columns if c not in IDENTITY_IGNORES and c not in swept]
    measured = [c for c in MEASURED if c in runs.columns]
    if runs.height < 2 or not measured:
        return {}
    size = pl.len().over("experiment")
    rounded = [
        pl.col(c).round_sig_figs(12) if runs.schema[c].is_float() else pl.col(c) for c in keys
    ]
    ordered = (
        runs.with_row_index("_row")
        .filter(pl.any_horizontal(pl.col(c).is_not_null() for c in measured))
        .with_columns(size.alias("_size"))
        .sort(["_size", "_row"], descending=[True, False])
    )
    groups = ordered.group_by(rounded, maintain_order=True).agg("run_id", "experiment")
    out: dict[str, str] = {}
    for ids, experiments in groups.select("run_id", "experiment").iter_rows():
        for rid, exp in zip(ids[1:], experiments[1:], strict=True):
            if exp != experiments[0]:
                out[rid] = ids[0]
    return out


def repeat_notes(t: Tables) -> dict[str, str]:
    """Each run left out as a repeat -> the note that says so, naming the run reported."""
    labels = dict(t.all_runs.select("run_id", "run").iter_rows())
    return {r: f"The same run as {labels[k]}: reported once, as that." for r, k in t.same.items()}


def once(frame: pl.DataFrame, same: dict[str, str]) -> pl.DataFrame:
    """The frame without the rows of runs left out as repeats."""
    if not same or "run_id" not in frame.columns:
        return frame
    return frame.filter(~pl.col("run_id").is_in(list(same)))


def with_labels(frame: pl.DataFrame, labels: pl.DataFrame) -> pl.DataFrame:
    """The frame with a `run` column (the label of `run_labels`) first, when it has run ids."""
    if "run_id" not in frame.columns or frame.is_empty():
        return frame
    run = pl.col("run_id").replace_strict(
        labels["run_id"], labels["run"], default=pl.col("run_id"), return_dtype=pl.String
    )
    return frame.with_columns(run.alias("run")).select("run", pl.exclude("run"))


def labelled(t: Tables) -> Tables:
    """`t` with each repeated run left out (its label added to the one kept) and every
    table's `run` label."""
    t.same = repeated_runs(t.runs, t.params)
    labels = run_labels(t.runs)
    t.all_runs = with_labels(t.runs, labels)
    if t.same:
        alias = labels.filter(pl.col("run_id").is_in(list(t.same))).select(
            pl.col("run_id").replace_strict(t.same).alias("kept"), pl.col("run").alias("also")
        )
        extra = alias.group_by("kept", maintain_order=True).agg(pl.col("also").str.join(", "))
        labels = labels.join(extra, left_on="run_id", right_on="kept", how="left").select(
            "run_id", pl.concat_str("run", "also", separator=" = ", ignore_nulls=True).alias("run")
        )
    t.runs, t.bounces, t.collisions, t.phases = (
        with_labels(once(f, t.same), labels) for f in (t.runs, t.bounces, t.collisions, t.phases)
    )
    t.studies = {n: with_labels(s, labels) for n, s in t.studies.items()}
    return t
