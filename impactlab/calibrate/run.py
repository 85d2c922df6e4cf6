"""Record a calibration grid, analyze the logs with the analysis stage, tabulate target vs measured.

The measured e comes only from the recorded logs, through the analysis stage
(`impactlab.analyze.run_analysis`, tables only): the bounces table for a ball on the floor
(``e_velocity``: normal velocity one logged step after the contact interval over the one one
step before it), the collisions table for two balls (``e_measured``, velocities, momentum).
The recorder's contact parameters only describe the runs and give the predictions.

Low-speed predictions (a ball on the floor, contact designed at 1 m/s, hitting slower):

- ``e_pred_release``: `restitution_with_gravity(contact_law="mujoco", timestep_s=dt,
  at="release")`: the velocity when the contact force lets go.
- ``e_pred_surface``: `restitution.surface_restitution`, the same step emulation continued
  until the ball is back at the surface (what the analysis measures, and what the contact is
  calibrated for at its design speed): after the force lets go the ball is still inside the
  floor and flies up against gravity for a while, which lowers the velocity further.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl

from impactlab.analyze import AnalysisResult, run_analysis
from impactlab.calibrate.bounces import all_points, column_max
from impactlab.calibrate.grid import GRAVITY_MPS2, RADIUS_M, Grid, GridPoint
from impactlab.contact import (
    RESTITUTION_TOLERANCE,
    restitution_with_gravity,
    surface_restitution,
)
from impactlab.errors import LogError
from impactlab.files import write_text
from impactlab.physics import collision_after
from impactlab.progress import Progress
from impactlab.record import plan, record_runs

PENETRATION_BOUND = 0.02
"""Max penetration the contact is designed for, as a fraction of the radius."""
VELOCITY_BOUND = 0.005
"""Post-collision velocities vs the 1D formula for the target e, relative to the closing speed."""
MOMENTUM_BOUND = 1e-9
"""Relative momentum change in a zero-gravity collision."""


@dataclass
class CalibrationResult:
    """What a calibration recorded, measured and wrote.

    Attributes:
        out_dir: the output folder.
        grid: the grid calibrated.
        points: one row per single-impact grid point (see `point_table`).
        summary: per kind: runs, max |error|, the worst point, failures (JSON-ready).
        bounces: one row per bounce of the multi-bounce drops (`bounces.bounce_table`).
        files: every file written (tables, summary, figures, report).
        figures: the PNGs (calibration.png, then lowspeed.png when there is a low-speed study).
        timings: seconds spent per stage ("specs", "record", "analyze", "total").
    """

    out_dir: Path
    grid: Grid
    points: pl.DataFrame
    summary: dict[str, Any]
    bounces: pl.DataFrame = field(default_factory=pl.DataFrame)
    files: list[Path] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def failures(self) -> pl.DataFrame:
        """Grid points (plane and ball) that miss a bound."""
        return self.points.filter((pl.col("kind") != "lowspeed") & ~pl.col("ok"))

    @property
    def failing_bounces(self) -> pl.DataFrame:
        """Bounces of the multi-bounce drops that miss their bound."""
        return self.bounces.filter(~pl.col("ok")) if self.bounces.height else self.bounces

    @property
    def exit_code(self) -> int:
        """0 when every grid point and every bounce is within its bounds, else 1."""
        missing = (self.summary.get("bounces") or {}).get("runs_without_bounces")
        return 1 if self.failures.height or self.failing_bounces.height or missing else 0


def write_specs(points: Sequence[GridPoint], folder: Path) -> list[Path]:
    """Write each point's spec as `<name>.toml` into `folder`."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for p in points:
        paths.append(write_text(folder / f"{p.name}.toml", p.toml))
    return paths


def record_and_analyze(
    points: Sequence[GridPoint], out_dir: Path, *, progress: Progress | None = None
) -> tuple[pl.DataFrame, AnalysisResult, dict[str, float]]:
    """Record every point (specs in out_dir/specs, logs in out_dir/logs), analyze the logs.

    Returns:
        The point table, the analysis stage's tables and the time spent per stage in s.

    Raises:
        LogError: a log cannot be analyzed.
    """
    t0 = time.perf_counter()
    specs = write_specs(points, out_dir / "specs")
    runs = plan(specs)
    t1 = time.perf_counter()
    recorded = record_runs(runs, out_dir / "logs", progress=progress)
    t2 = time.perf_counter()
    result = run_analysis(recorded.paths, progress=progress)
    if result.failed:
        raise LogError(*result.failed[0])
    partial = result.runs.filter(pl.col("partial")) if result.runs.height else result.runs
    if partial.height:
        raise LogError(partial["file"][0], "partial log: " + partial["problems"][0])
    table = point_table(points, result.runs, result.bounces, result.collisions)
    t3 = time.perf_counter()
    return table, result, {"specs": t1 - t0, "record": t2 - t1, "analyze": t3 - t2}


def point_table(
    points: Sequence[GridPoint],
    runs: pl.DataFrame,
    bounces: pl.DataFrame,
    collisions: pl.DataFrame,
) -> pl.DataFrame:
    """One row per grid point: design, measurement (analysis tables) and bounds.

    Columns: kind, name, target, speed_mps, m1_kg, m2_kg, design_speed_mps, timestep_s,
    stiffness, damping, zeta, duration_design_s, steps_per_contact, run_id, e_measured,
    error, v_in_mps, v_out_mps (floor), v1/v2 before/after and analytic (ball),
    velocity_error_rel, momentum_rel_change, max_penetration_m, penetration_frac,
    e_pred_release, e_pred_surface (lowspeed), ok, note.
    """
    run_of = dict(zip(runs["experiment"], runs["run_id"], strict=True))
    rows = []
    for p in (q for q in points if q.kind != "bounces"):
        run_id = run_of.get(p.name)
        row = {
            "kind": p.kind,
            "name": p.name,
            "target": p.target,
            "speed_mps": p.speed,
            "m1_kg": p.m1,
            "m2_kg": p.m2,
            "design_speed_mps": p.design_speed,
            "timestep_s": p.timestep,
            "stiffness": p.params.stiffness,
            "damping": p.params.damping,
            "zeta": p.params.zeta,
            "duration_design_s": p.params.duration_s,
            "steps_per_contact": p.params.duration_s / p.timestep,
            "gravity_shift_est": _gravity_shift(p),
            "run_id": run_id,
        }
        row.update(_measurement(p, run_id, bounces, collisions))
        if p.kind == "lowspeed":
            row["e_pred_release"] = restitution_with_gravity(
                p.params,
                impact_speed_mps=p.speed,
                gravity_mps2=GRAVITY_MPS2,
                contact_law="mujoco",
                timestep_s=p.timestep,
                at="release",
            )
            row["e_pred_surface"] = surface_restitution(
                p.params, impact_speed_mps=p.speed, gravity_mps2=GRAVITY_MPS2, timestep_s=p.timestep
            )
        rows.append(row)
    frame = pl.DataFrame(rows, infer_schema_length=None)
    for col in ("e_pred_release", "e_pred_surface", "m2_kg"):
        if col not in frame.columns:
            frame = frame.with_columns(pl.lit(None, dtype=pl.Float64).alias(col))
    return frame


def _gravity_shift(p: GridPoint) -> float:
    """First-order change of the surface-to-surface e by gravity at the design speed, for a
    ball on the floor: -2 zeta g / (w0 v) (see `surface_restitution`); 0 without gravity."""
    if p.kind == "ball":
        return 0.0
    w0 = math.sqrt(p.params.stiffness)
    return -2.0 * p.params.zeta * GRAVITY_MPS2 / (w0 * p.design_speed)


def _measurement(
    p: GridPoint, run_id: str | None, bounces: pl.DataFrame, collisions: pl.DataFrame
) -> dict[str, Any]:
    """The analysis stage's measurement of one point, and whether it meets the bounds."""
    nan = float("nan")
    out: dict[str, Any] = {
        "e_measured": nan,
        "error": nan,
        "v_in_mps": nan,
        "v_out_mps": nan,
        "v1_before_mps": nan,
        "v2_before_mps": nan,
        "v1_after_mps": nan,
        "v2_after_mps": nan,
        "v1_after_target_mps": nan,
        "v2_after_target_mps": nan,
        "velocity_error_rel": nan,
        "momentum_rel_change": nan,
        "max_penetration_m": nan,
        "penetration_frac": nan,
        "ok": False,
        "note": "",
    }
    if run_id is None:
        out["note"] = "no log"
        return out
    if p.kind in ("plane", "lowspeed"):
        rows = bounces.filter((pl.col("run_id") == run_id) & (pl.col("bounce") == 1))
        if rows.is_empty():
            out["note"] = "no bounce in the log"
            return out
        b = rows.row(0, named=True)
        out["v_in_mps"] = -b["v_in_mps"] if b["v_in_mps"] is not None else nan
        out["max_penetration_m"] = b["max_penetration_m"]
        if b["complete"]:
            out["v_out_mps"] = b["v_out_mps"]
            out["e_measured"] = b["e_velocity"]
        else:
            out["note"] = b["note"] or "incomplete bounce"
    else:
        rows = collisions.filter((pl.col("run_id") == run_id) & pl.col("complete"))
        if rows.is_empty():
            out["note"] = "no complete collision in the log"
            return out
        c = rows.row(0, named=True)
        v1, v2 = c["v1n_before_mps"], c["v2n_before_mps"]
        # the normal points from body1 to body2 = +x; the balls' velocities along it
        t1, t2 = collision_after(c["m1_kg"], c["m2_kg"], v1, v2, p.target)
        closing = v1 - v2
        out.update(
            e_measured=c["e_velocity"],
            v1_before_mps=v1,
            v2_before_mps=v2,
            v1_after_mps=c["v1n_after_mps"],
            v2_after_mps=c["v2n_after_mps"],
            v1_after_target_mps=t1,
            v2_after_target_mps=t2,
            velocity_error_rel=max(abs(c["v1n_after_mps"] - t1), abs(c["v2n_after_mps"] - t2))
            / abs(closing),
            momentum_rel_change=c["momentum_rel_change"],
            max_penetration_m=c["max_penetration_m"],
        )
    out["error"] = out["e_measured"] - p.target
    out["penetration_frac"] = out["max_penetration_m"] / RADIUS_M
    problems = []
    if not abs(out["error"]) <= RESTITUTION_TOLERANCE:
        problems.append(f"|e - target| = {abs(out['error']):.4f} > {RESTITUTION_TOLERANCE}")
    if not out["penetration_frac"] <= PENETRATION_BOUND:
        problems.append(f"penetration {out['penetration_frac']:.2%} of the radius")
    if p.kind == "ball":
        if not out["velocity_error_rel"] <= VELOCITY_BOUND:
            off = out["velocity_error_rel"]
            problems.append(f"velocities off by {off:.2%} of the closing speed")
        if not out["momentum_rel_change"] <= MOMENTUM_BOUND:
            problems.append(f"momentum changed by {out['momentum_rel_change']:.2e}")
    out["ok"] = not problems
    out["note"] = "; ".join([out["note"], *problems]).strip("; ")
    return out


def lowspeed_curves(points: Sequence[GridPoint], n: int = 20) -> pl.DataFrame:
    """Both predictions over log-spaced impact speeds, per target of the low-speed study.

    Returns:
        (target, speed_mps, e_pred_release, e_pred_surface); empty without low-speed points.
    """
    low = [p for p in points if p.kind == "lowspeed"]
    schema = {k: pl.Float64 for k in ("target", "speed_mps", "e_pred_release", "e_pred_surface")}
    if not low:
        return pl.DataFrame(schema=schema)
    speeds = np.geomspace(min(p.speed for p in low), max(p.speed for p in low), n)
    rows = []
    for target in sorted({p.target for p in low}):
        p = next(q for q in low if q.target == target)
        surface = surface_restitution(
            p.params, impact_speed_mps=speeds, gravity_mps2=GRAVITY_MPS2, timestep_s=p.timestep
        )
        for v, e_s in zip(speeds, surface, strict=True):
            e_r = restitution_with_gravity(
                p.params,
                impact_speed_mps=float(v),
                gravity_mps2=GRAVITY_MPS2,
                contact_law="mujoco",
                timestep_s=p.timestep,
                at="release",
            )
            rows.append((target, float(v), e_r, float(e_s)))
    return pl.DataFrame(rows, schema=schema, orient="row")


FAILURE_COLUMNS = (
    "name",
    "target",
    "speed_mps",
    "e_measured",
    "error",
    "gravity_shift_est",
    "note",
)


def _worst(frame: pl.DataFrame) -> dict[str, Any] | None:
    if frame.is_empty() or frame["error"].drop_nans().is_empty():
        return None
    row = frame.filter(pl.col("error").is_not_nan()).sort(pl.col("error").abs()).row(-1, named=True)
    keys = ("name", "target", "speed_mps", "m1_kg", "m2_kg", "e_measured", "error", "timestep_s")
    return {k: row[k] for k in keys}


def summarize(points: pl.DataFrame) -> dict[str, Any]:
    """Per kind: runs, max |error|, max penetration, worst point and failing points."""
    out: dict[str, Any] = {}
    for kind in ("plane", "ball"):
        f = points.filter(pl.col("kind") == kind)
        if f.is_empty():
            continue
        err = f["error"].drop_nans().abs().to_frame()
        entry = {
            "runs": f.height,
            "measured": int(f["e_measured"].is_not_nan().sum()),
            "max_abs_error": float(err.max().item()) if err.height else None,
            "mean_abs_error": float(err.mean().item()) if err.height else None,
            "max_penetration_frac": column_max(f, pl.col("penetration_frac")),
            "worst": _worst(f),
            "failures": f.filter(~pl.col("ok")).select(FAILURE_COLUMNS).to_dicts(),
        }
        if kind == "ball":
            entry["max_velocity_error_rel"] = column_max(f, pl.col("velocity_error_rel"))
            entry["max_momentum_rel_change"] = column_max(f, pl.col("momentum_rel_change"))
        out[kind] = entry
    low = points.filter(pl.col("kind") == "lowspeed")
    if low.height:
        out["lowspeed"] = {
            "runs": low.height,
            "design_speed_mps": float(low["design_speed_mps"][0]),
            "max_abs_diff_release": column_max(
                low, (pl.col("e_measured") - pl.col("e_pred_release")).abs()
            ),
            "max_abs_diff_surface": column_max(
                low, (pl.col("e_measured") - pl.col("e_pred_surface")).abs()
            ),
            "points": low.select(
                "target", "speed_mps", "e_measured", "e_pred_release", "e_pred_surface"
            ).to_dicts(),
        }
    return out


def calibrate(
    grid: Grid, out_dir: Path, *, echo: Callable[[str], None], progress: Progress | None = None
) -> tuple[list[GridPoint], pl.DataFrame, AnalysisResult, dict[str, float]]:
    """Build the grid's points, record, analyze.

    Returns:
        The points, the point table, the analysis stage's tables and the timings in s.
    """
    t0 = time.perf_counter()
    points = all_points(grid)
    echo(
        f"calibration grid {grid.name}: {len(points)} runs "
        f"({sum(p.kind == 'plane' for p in points)} ball-plane, "
        f"{sum(p.kind == 'ball' for p in points)} ball-ball, "
        f"{sum(p.kind == 'lowspeed' for p in points)} low-speed, "
        f"{sum(p.kind == 'bounces' for p in points)} multi-bounce)"
    )
    table, analysis, timings = record_and_analyze(points, out_dir, progress=progress)
    echo(
        f"{len(points)} runs: specs {timings['specs']:.1f} s, record {timings['record']:.1f} s, "
        f"analyze {timings['analyze']:.1f} s"
    )
    timings["grid"] = time.perf_counter() - t0 - sum(timings.values())
    return points, table, analysis, timings


def bounds() -> dict[str, float]:
    """The bounds every ball-plane and ball-ball point is checked against."""
    return {
        "restitution_abs": RESTITUTION_TOLERANCE,
        "penetration_frac_of_radius": PENETRATION_BOUND,
        "collision_velocity_rel_closing_speed": VELOCITY_BOUND,
        "collision_momentum_rel": MOMENTUM_BOUND,
    }
