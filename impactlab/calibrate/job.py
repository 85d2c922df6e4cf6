"""The calibration job: how well does a target restitution come out of recorded logs?

Records a grid of short impacts with calibrated contacts (``[contact] restitution = e``): a ball
on the floor with gravity and two balls head-on in zero gravity, over targets e, impact speeds
and masses, plus a low-speed study on the floor (contact designed at 1 m/s, hitting at
0.05 .. 1 m/s) and multi-bounce drops (every bounce checked: in the contact's speed range
against the target, below it against the designer's prediction). The logs are analyzed by the
analysis stage; the command prints target vs measured e, and writes to the output folder:

- ``points.parquet`` (one row per single-impact grid point), ``lowspeed_curves.parquet``
  (predictions), ``multibounce.parquet`` (one row per bounce of the drops), ``runs.parquet``,
  ``bounces.parquet``, ``collisions.parquet`` (the analysis stage's tables),
- ``summary.json``, ``calibration.png``, ``lowspeed.png``, ``bounces.png``, ``calibration.md``,
- ``specs/`` (the generated TOML specs) and ``logs/`` (the MCAP logs, unless discarded).

Exit code 0 when every ball-plane and ball-ball point and every bounce meets its bounds, 1
otherwise.
"""

from __future__ import annotations

import math
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path

from impactlab.calibrate import plots
from impactlab.calibrate.bounces import bounce_table, prediction_curves, summarize_bounces
from impactlab.calibrate.grid import GRIDS, RADIUS_M, Grid
from impactlab.calibrate.report import report, text_table
from impactlab.calibrate.run import (
    CalibrationResult,
    bounds,
    calibrate,
    lowspeed_curves,
    summarize,
)
from impactlab.contact import RESTITUTION_FLOOR
from impactlab.errors import SpecError
from impactlab.files import check_writable, full_disk_error, write_json, write_parquet, write_text
from impactlab.progress import Progress

__all__ = ["CalibrationResult", "choose_grid", "run_calibration"]


def choose_grid(
    *,
    quick: bool,
    grid: str | Grid | None = None,
    targets: Sequence[float] | None = None,
    speeds: Sequence[float] | None = None,
    masses: Sequence[float] | None = None,
) -> Grid:
    """The grid to run: `grid` (a name or a Grid), else quick or full; lists replaced.

    Raises:
        SpecError: an unknown grid name, or a target, speed or mass out of range or listed
            twice.
    """
    if isinstance(grid, Grid):
        base = grid
    elif grid is not None:
        if grid not in GRIDS:
            raise SpecError("--grid", "", f"unknown grid {grid!r} (known: {', '.join(GRIDS)})")
        base = GRIDS[grid]
    else:
        base = GRIDS["quick" if quick else "full"]
    checks: tuple[tuple[str, Sequence[float] | None, Callable[[float], bool], str], ...] = (
        ("--targets", targets, lambda e: RESTITUTION_FLOOR <= e <= 1.0, "in [0.1354, 1]"),
        ("--speeds", speeds, lambda v: 0.0 < v <= 100.0, "in (0, 100] m/s"),
        ("--masses", masses, lambda m: 0.0 < m <= 1e4, "in (0, 1e4] kg"),
    )
    for flag, values, ok, rule in checks:
        bad = [x for x in values or () if not (math.isfinite(x) and ok(x))]
        if bad:
            raise SpecError(flag, "", f"{bad[0]!r} is out of range (must be {rule})")
        twice = [x for i, x in enumerate(values or ()) if x in list(values or ())[:i]]
        if twice:
            raise SpecError(flag, "", f"lists {twice[0]!r} twice: give each value once")
    return base.with_values(targets=targets, speeds=speeds, masses=masses)


def run_calibration(
    out_dir: Path,
    *,
    quick: bool = False,
    echo: Callable[[str], None] = print,
    grid: str | Grid | None = None,
    targets: Sequence[float] | None = None,
    speeds: Sequence[float] | None = None,
    masses: Sequence[float] | None = None,
    keep_logs: bool = True,
    progress: Progress | None = None,
) -> CalibrationResult:
    """Record and analyze a calibration grid, write tables, figures and calibration.md.

    Args:
        out_dir: output folder (created).
        quick: use the quick grid (when `grid` is None); else the full grid.
        echo: where the printed table and progress go.
        grid: "quick", "medium", "full" or a Grid; overrides `quick`.
        targets, speeds, masses: replace the grid's lists.
        keep_logs: keep the MCAP logs in out_dir/logs.
        progress: receives the grid's recording and analysis progress; None: silent.

    Returns:
        The point table, the summary, the files written and the timings.

    Raises:
        SpecError: a bad grid value or an output folder that cannot be written.
    """
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    chosen = choose_grid(quick=quick, grid=grid, targets=targets, speeds=speeds, masses=masses)
    created = not out_dir.exists()
    check_writable(out_dir)
    try:
        with full_disk_error(out_dir):
            return _calibrate_into(
                out_dir, chosen, echo=echo, keep_logs=keep_logs, t0=t0, progress=progress
            )
    except BaseException:  # a folder this job created holds only its own partial work
        if created:
            shutil.rmtree(out_dir, ignore_errors=True)
        raise


def _calibrate_into(
    out_dir: Path,
    chosen: Grid,
    *,
    echo: Callable[[str], None],
    keep_logs: bool,
    t0: float,
    progress: Progress | None,
) -> CalibrationResult:
    """`run_calibration` once the output folder is checked: record, analyze, write."""
    points, table, analysis, timings = calibrate(chosen, out_dir, echo=echo, progress=progress)
    t1 = time.perf_counter()
    curves = lowspeed_curves(points)
    multi = bounce_table(points, analysis.runs, analysis.bounces)
    summary = summarize(table)
    summary["bounces"] = summarize_bounces(multi, points)
    result = CalibrationResult(out_dir, chosen, table, summary, bounces=multi)
    files = [
        write_parquet(table, out_dir / "points.parquet"),
        write_parquet(curves, out_dir / "lowspeed_curves.parquet"),
        write_parquet(analysis.runs, out_dir / "runs.parquet"),
        write_parquet(analysis.bounces, out_dir / "bounces.parquet"),
        write_parquet(analysis.collisions, out_dir / "collisions.parquet"),
    ]
    if multi.height:
        files.append(write_parquet(multi, out_dir / "multibounce.parquet"))
    figs = [
        plots.calibration_figure(
            table,
            title=f"Target vs measured restitution ({chosen.name} grid, {table.height} runs)",
            path=out_dir / "calibration.png",
        )
    ]
    if curves.height:
        figs.append(
            plots.lowspeed_figure(
                table,
                curves,
                title=f"Ball on the floor below the design speed "
                f"({chosen.design_speed:g} m/s): e depends on the impact speed",
                path=out_dir / "lowspeed.png",
            )
        )
    if multi.height:
        figs.append(
            plots.bounces_figure(
                multi,
                prediction_curves(points),
                title="Every bounce of a drop (filled: in the contact's speed range; "
                "line: the designer's prediction)",
                path=out_dir / "bounces.png",
            )
        )
    files += figs
    timings["predict_plot"] = time.perf_counter() - t1
    if not keep_logs:
        shutil.rmtree(out_dir / "logs", ignore_errors=True)
    timings["total"] = time.perf_counter() - t0
    result.timings = timings
    lines = text_table(result)
    for line in lines:
        echo(line)
    summary_doc = {
        "grid": {
            "name": chosen.name,
            "targets": chosen.targets,
            "speeds_mps": chosen.speeds,
            "masses_kg": chosen.masses,
            "ball_mass_pairs_kg": chosen.mass_pairs(),
            "low_targets": chosen.low_targets,
            "low_speeds_mps": chosen.low_speeds,
            "bounce_cases": [asdict(c) for c in chosen.bounce_cases],
            "design_speed_mps": chosen.design_speed,
            "radius_m": RADIUS_M,
        },
        "bounds": bounds(),
        "results": summary,
        "timings_s": timings,
        "exit_code": result.exit_code,
    }
    files.append(write_json(out_dir / "summary.json", summary_doc))
    files.append(write_text(out_dir / "calibration.md", report(result, curves, figs)))
    result.files = files
    result.figures = list(figs)
    echo(f"calibration written to {out_dir}/ ({timings['total']:.1f} s)")
    return result
