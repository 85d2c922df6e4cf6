"""The calibration's text: the console table and calibration.md."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import polars as pl

from impactlab.calibrate.bounces import report_lines
from impactlab.calibrate.run import CalibrationResult, bounds

KIND_LABEL = {"plane": "ball-plane (gravity)", "ball": "ball-ball (zero gravity)"}


def per_target(points: pl.DataFrame) -> pl.DataFrame:
    """Per target e and kind: runs, measured range, max |error| and where it is largest."""
    return (
        points.filter(pl.col("kind").is_in(["plane", "ball"]) & pl.col("error").is_not_nan())
        .sort(pl.col("error").abs())
        .group_by("target", "kind")
        .agg(
            pl.len().alias("runs"),
            pl.col("e_measured").min().alias("e_min"),
            pl.col("e_measured").max().alias("e_max"),
            pl.col("error").abs().max().alias("max_abs_error"),
            pl.col("speed_mps").last().alias("worst_speed_mps"),
            (~pl.col("ok")).sum().alias("failing"),
        )
        .sort("target", "kind")
    )


def text_table(result: CalibrationResult) -> list[str]:
    """The printed table: target vs measured per kind, the worst points, failures, low speed."""
    pts = result.points
    summary = result.summary
    rows = per_target(pts)
    lines = [
        "",
        f"{'target e':>8} | {'ball-plane (gravity): measured':>32} {'max|err|':>9} | "
        f"{'ball-ball (zero g): measured':>30} {'max|err|':>9}",
    ]
    for target in sorted(rows["target"].unique().to_list()):
        cells = []
        for kind, width in (("plane", 32), ("ball", 30)):
            r = rows.filter((pl.col("target") == target) & (pl.col("kind") == kind))
            if r.is_empty():
                cells.append(f"{'-':>{width}} {'-':>9}")
                continue
            d = r.row(0, named=True)
            flag = "*" if d["failing"] else " "
            rng = f"{d['e_min']:.4f} .. {d['e_max']:.4f} ({d['runs']} runs)"
            cells.append(f"{rng:>{width}} {d['max_abs_error']:>8.4f}{flag}")
        lines.append(f"{target:>8.3g} | {cells[0]} | {cells[1]}")
    for kind, entry in ((k, summary.get(k)) for k in ("plane", "ball")):
        if not entry or entry.get("worst") is None:
            continue
        w = entry["worst"]
        masses = f"{w['m1_kg']:g} kg" + (f" / {w['m2_kg']:g} kg" if w["m2_kg"] else "")
        lines.append(
            f"{KIND_LABEL[kind]}: max |error| {entry['max_abs_error']:.4f} over "
            f"{entry['measured']} runs, worst: target {w['target']:g}, {w['speed_mps']:g} m/s, "
            f"{masses}: measured {w['e_measured']:.4f}; max penetration "
            f"{entry['max_penetration_frac']:.2%} of the radius"
            + (
                f"; velocities within {entry['max_velocity_error_rel']:.3%} of the closing "
                f"speed, momentum {entry['max_momentum_rel_change']:.1e}"
                if kind == "ball"
                else ""
            )
        )
    fails = result.failures
    if fails.height:
        lines.append(f"* {fails.height} point(s) miss a bound:")
        for d in fails.iter_rows(named=True):
            lines.append(
                f"  {d['name']}: measured {d['e_measured']:.4f} ({d['note']}); "
                f"gravity estimate -2 zeta g / (w0 v) = {d['gravity_shift_est']:+.4f}"
            )
    mb = summary.get("bounces")
    if mb and mb["bounces"]:
        lines.append(
            f"multi-bounce drops: {mb['runs']} runs, {mb['in_range']} bounces in the contact's "
            f"speed range, max |error| {mb['max_abs_error_in_range'] or 0:.4f}; "
            f"{mb['below_range']} below it, max |measured - predicted| "
            f"{mb['max_abs_diff_predicted_below'] or 0:.4f}; "
            f"{len(mb['failures'])} bounce(s) miss their bound"
        )
        for d in mb["failures"]:
            lines.append(
                f"  * {d['name']} bounce {d['bounce']} at {d['v_in_mps']:.3f} m/s: measured "
                f"{d['e_measured']:.4f}, predicted {d['e_predicted']:.4f} "
                f"({'in' if d['in_range'] else 'below'} the range)"
            )
    low = pts.filter(pl.col("kind") == "lowspeed").sort("target", "speed_mps")
    if low.height:
        lines.append(
            f"low speed (contact designed at {low['design_speed_mps'][0]:g} m/s): "
            "below the speed range; target, speed -> measured | predicted at release | "
            "predicted back at the surface"
        )
        for d in low.iter_rows(named=True):
            lines.append(
                f"  e {d['target']:g}, {d['speed_mps']:g} m/s -> {d['e_measured']:.4f} | "
                f"{d['e_pred_release']:.4f} | {d['e_pred_surface']:.4f}"
            )
    return lines


def _md_table(frame: pl.DataFrame, formats: dict[str, str]) -> list[str]:
    cols = list(formats)
    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for row in frame.select(cols).iter_rows(named=True):
        cells = []
        for c in cols:
            v = row[c]
            if v is None or (isinstance(v, float) and math.isnan(v)):
                cells.append("")
            else:
                cells.append(format(v, formats[c]).replace("|", "\\|"))
        out.append("| " + " | ".join(cells) + " |")
    return out


def report(result: CalibrationResult, curves: pl.DataFrame, figures: Sequence[Path]) -> str:
    """calibration.md: what ran, target vs measured, bounds and failures, the low-speed study."""
    g = result.grid
    pts = result.points
    s = result.summary
    t = result.timings
    main = pts.filter(pl.col("kind") != "lowspeed")
    dt_lo, dt_hi, steps_lo, steps_hi = main.select(
        pl.col("timestep_s").min().alias("dt_lo"),
        pl.col("timestep_s").max().alias("dt_hi"),
        pl.col("steps_per_contact").min().alias("steps_lo"),
        pl.col("steps_per_contact").max().alias("steps_hi"),
    ).row(0)
    lines = [
        f"# Restitution calibration ({g.name} grid)",
        "",
        "Each single-impact run is one impact with a calibrated contact "
        "(`[contact] restitution = e`, "
        "`impactlab.contact`), recorded to an MCAP log and analyzed by the analysis "
        "stage: e = -v_out / v_in with the normal velocities one logged step before and one "
        "after the contact interval (every step is logged). Ball on the floor: radius 0.1 m, "
        "gravity 9.81 m/s^2, starting a few steps above the floor at the impact speed, contact "
        "designed for that speed (a speed range of one speed). Two balls: radius 0.1 m, zero "
        "gravity, head-on, ball 1 at "
        "+0.6 v and ball 2 at -0.4 v, masses (m1, m2) = "
        + ", ".join(f"({a:g}, {b:g})" for a, b in g.mass_pairs())
        + " kg. Timestep: the largest of 5e-5 .. 5e-7 s the restitution module accepts "
        f"(here {dt_lo:g} .. {dt_hi:g} s, {steps_lo:.0f} .. {steps_hi:.0f} steps "
        "per contact).",
        "",
        f"Targets {', '.join(f'{x:g}' for x in g.targets)}; speeds "
        f"{', '.join(f'{x:g}' for x in g.speeds)} m/s; masses "
        f"{', '.join(f'{x:g}' for x in g.masses)} kg: {pts.height} runs, "
        f"{t.get('total', 0):.0f} s (record {t.get('record', 0):.0f} s, analyze "
        f"{t.get('analyze', 0):.0f} s).",
        "",
        "## Target vs measured",
        "",
    ]
    rows = per_target(pts).with_columns(
        pl.col("kind").replace_strict(KIND_LABEL, default=pl.col("kind"))
    )
    lines += _md_table(
        rows,
        {
            "target": "g",
            "kind": "s",
            "runs": "d",
            "e_min": ".4f",
            "e_max": ".4f",
            "max_abs_error": ".4f",
            "worst_speed_mps": "g",
            "failing": "d",
        },
    )
    lines.append("")
    for kind in ("plane", "ball"):
        e = s.get(kind)
        if not e or e.get("worst") is None:
            continue
        w = e["worst"]
        lines.append(
            f"- {KIND_LABEL[kind]}: max |error| **{e['max_abs_error']:.4f}** (mean "
            f"{e['mean_abs_error']:.4f}), worst at target {w['target']:g}, {w['speed_mps']:g} "
            f"m/s ({w['name']}); max penetration {e['max_penetration_frac']:.2%} of the radius"
            + (
                f"; post-collision velocities within {e['max_velocity_error_rel']:.3%} of the "
                f"closing speed of the 1D formula for the target e; momentum conserved to "
                f"{e['max_momentum_rel_change']:.1e} (relative)."
                if kind == "ball"
                else "."
            )
        )
    b = bounds()
    lines += [
        "",
        f"Bounds: |e - target| <= {b['restitution_abs']}, max penetration <= "
        f"{b['penetration_frac_of_radius']:.0%} of the radius; collisions also: velocities "
        f"after within {b['collision_velocity_rel_closing_speed']:.1%} of the closing speed "
        f"of the 1D formula, momentum to {b['collision_momentum_rel']:g}.",
        "",
    ]
    fails = result.failures
    if fails.height:
        lines += [
            f"**{fails.height} point(s) miss a bound:**",
            "",
            *_md_table(
                fails,
                {
                    "name": "s",
                    "target": "g",
                    "speed_mps": "g",
                    "e_measured": ".4f",
                    "error": "+.4f",
                    "gravity_shift_est": "+.4f",
                    "note": "s",
                },
            ),
            "",
            "A point that misses a bound is a measurement the contact model did not "
            "predict: its designer promises the bound at every impact speed of the contact's "
            "range (docs/contact-model.md). The bound is not loosened here; "
            "`gravity_shift_est` is the first-order change of e by gravity, -2 zeta g / (w0 v).",
            "",
        ]
    else:
        lines += ["Every point meets the bounds.", ""]
    low = pts.filter(pl.col("kind") == "lowspeed").sort("target", "speed_mps")
    if low.height:
        lines += [
            "## Low impact speeds on the floor",
            "",
            f"A contact designed at {g.design_speed:g} m/s, a ball of {g.low_mass:g} kg hitting "
            "it more slowly: these impacts lie below the contact's speed range, where the "
            "promise |e - target| <= 0.005 does not apply (docs/contact-model.md). At low "
            "speed gravity acts for a larger share of the contact and holds the ball in it, "
            "so e falls below the target; the designer predicts by how much. *predicted at "
            "release* is e from the velocity when the contact force lets go; *predicted back at "
            "the surface* follows the ball on until it is back at the surface, which is what "
            "the analysis measures (and what the contact is calibrated for inside its range).",
            "",
            *_md_table(
                low.rename(
                    {
                        "speed_mps": "impact speed (m/s)",
                        "e_measured": "measured e",
                        "e_pred_release": "predicted at release",
                        "e_pred_surface": "predicted back at the surface",
                        "timestep_s": "timestep (s)",
                    }
                ),
                {
                    "target": "g",
                    "impact speed (m/s)": "g",
                    "measured e": ".4f",
                    "predicted at release": ".4f",
                    "predicted back at the surface": ".4f",
                    "timestep (s)": "g",
                },
            ),
            "",
            f"Largest |measured - predicted at release| "
            f"{s['lowspeed']['max_abs_diff_release']:.4f}; largest |measured - predicted back "
            f"at the surface| {s['lowspeed']['max_abs_diff_surface']:.4f}.",
            "",
        ]
    lines += report_lines(result.bounces, s.get("bounces"))
    lines += ["## Figures", ""]
    lines += [f"![{p.stem}]({p.name})" for p in figures]
    lines += [
        "",
        "## Files",
        "",
        "`points.parquet` (one row per single-impact run: design, measurement, bounds), "
        "`lowspeed_curves.parquet`, `multibounce.parquet` (one row per bounce of the drops), "
        "the analysis stage's `runs.parquet`, `bounces.parquet`, "
        "`collisions.parquet`, `summary.json`, `specs/` (the generated specs), `logs/`.",
        "",
    ]
    return "\n".join(lines)
