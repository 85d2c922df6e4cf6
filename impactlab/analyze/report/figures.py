"""Figures drawn from the analysis frames (each: frames, a title, a path -> one PNG)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib
import matplotlib.ticker
import numpy as np
import polars as pl

from impactlab.analyze.measure.bounces import TURNING
from impactlab.analyze.report.decimate_lines import thinned
from impactlab.physics import collision_after
from impactlab.plotting import plain, save_figure, styled, subplots

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.collections import Collection

MAX_LEGEND_LINES = 12  # beyond this, lines go unlabelled (runs coloured along the sweep)
MAX_SPEED_LABELS = 8  # a study figure writes the impact speed of at most this many runs


def _shade_contacts(ax: Axes, intervals: pl.DataFrame) -> Collection | None:
    """Shade contact intervals, all in one artist (a resting ball has thousands of them)."""
    if not intervals.height:
        return None
    spans = [(t0, t1 - t0) for t0, t1 in intervals.select("start_t_s", "end_t_s").iter_rows()]
    return ax.broken_barh(
        spans, (0, 1), transform=ax.get_xaxis_transform(), color="0.85", lw=0, label="contact"
    )


def _energy_lines(energy: pl.DataFrame) -> tuple[list[tuple[str, Any, Any]], list[Any]]:
    """The energy figure's lines, thinned (`decimate_lines`): (body, t, height) per body and
    (t, y) of kinetic, potential, total and, when logged, MuJoCo's total."""
    heights = []
    for body, frame in energy.filter(~pl.col("is_total")).group_by("body", maintain_order=True):
        heights.append(
            (str(body[0]), *thinned(frame["t_s"].to_numpy(), frame["height_m"].to_numpy()))
        )
    total = energy.filter(pl.col("is_total"))
    t = total["t_s"].to_numpy()
    ys = [total["ke_trans_J"] + total["ke_rot_J"], total["pe_J"], total["total_J"]]
    if total["mujoco_total_J"].drop_nulls().len():
        ys.append(total["mujoco_total_J"])
    return heights, [thinned(t, y.to_numpy()) for y in ys]


@styled
def energy_figure(energy: pl.DataFrame, contacts: pl.DataFrame, *, title: str, path: Path) -> Path:
    """Height above the contact height per body (top) and the run's energies (bottom), over
    the logged time only.

    Args:
        energy: `run_energy` of one run.
        contacts: the run's contact phases (start_t_s, end_t_s), shaded.
    """
    heights, energies = _energy_lines(energy)
    fig, (ax_h, ax_e) = subplots(2, 1, figsize=(9, 7), sharex=True)
    named = len(heights) <= MAX_LEGEND_LINES
    for body, t, h in heights:
        ax_h.plot(t, h, label=plain(body) if named else None)
    _shade_contacts(ax_h, contacts)
    ax_h.set_ylabel("lowest point above the ground (m)")
    ax_h.set_title(plain(title if named else f"{title}\n{len(heights)} bodies, one line each"))
    if ax_h.get_legend_handles_labels()[0]:  # many bodies and no contact: nothing to name
        ax_h.legend(loc="upper right")
    styles: list[tuple[tuple[str, ...], dict[str, Any]]] = [
        ((), {"label": "kinetic", "alpha": 0.8}),
        ((), {"label": "potential (zero at rest on the ground)", "alpha": 0.8}),
        ((), {"label": "total", "lw": 2, "color": "k"}),
        (("--",), {"lw": 1, "color": "tab:red", "label": "MuJoCo total (shifted)"}),
    ]
    for (t, y), (fmt, style) in zip(energies, styles, strict=False):
        ax_e.plot(t, y, *fmt, **style)
    _shade_contacts(ax_e, contacts)
    ax_e.set(xlabel="time (s)", ylabel="energy (J)")
    ax_e.legend(loc="center right")
    times = energy["t_s"]
    if times.len():
        ax_e.set_xlim(float(times.min()), float(times.max()))  # type: ignore[arg-type]
    for ax in (ax_h, ax_e):
        ax.grid(True, alpha=0.3)
    return save_figure(fig, path)


@styled
def bounce_decay_figure(
    bounces: pl.DataFrame, labels: dict[str, str], *, title: str, path: Path
) -> Path:
    """Apex height above the surface against bounce number, one line per run, body and surface.

    Args:
        bounces: bounce rows of several runs (run_id, body, surface, bounce, apex_before_m,
            apex_m).
        labels: run_id -> legend label.
    """
    fig, ax = subplots(figsize=(8, 5))
    rows = bounces.filter(
        pl.col("run_id").is_in(list(labels)) & pl.col("bounce").is_not_null()
    ).sort("bounce")
    groups = rows.partition_by("run_id", "body", "surface", maintain_order=True, as_dict=True)
    keys = [(str(r), str(b), str(s)) for r, b, s in groups]
    several = len({(b, s) for _, b, s in keys}) > 1
    legend = len(keys) <= MAX_LEGEND_LINES
    colors = matplotlib.colormaps["viridis"](np.linspace(0, 1, max(len(keys), 1)))
    drawn = set()
    for i, ((run_id, body, surface), mine) in enumerate(zip(keys, groups.values(), strict=True)):
        n = [0, *mine["bounce"].to_list()]
        h = [mine["apex_before_m"][0], *mine["apex_m"].to_list()]
        pts = [(a, b) for a, b in zip(n, h, strict=True) if b is not None]
        # the last contact of a run that comes to rest has no apex: show it at 0 (resting)
        if mine["apex_m"][-1] is None and not mine["complete"][-1]:
            pts.append((n[-1], 0.0))
        label = plain(labels[run_id] + (f", {body} on {surface}" if several else ""))
        start = f" (h0 = {h[0]:.3g} m)" if h[0] is not None else ""
        if len(pts) < 2 and mine["apex_m"].is_null().all():
            start += ": no apex measured after a bounce" + (
                " (turns in flight)" if (mine["note"] == TURNING).any() else ""
            )
        if pts:
            ax.plot(
                *zip(*pts, strict=True),
                "o-",
                color=None if legend else colors[i],
                label=f"{label}{start}" if legend else None,
            )
            drawn.add(run_id)
    for run_id, label in labels.items():
        if run_id not in drawn and legend:
            ax.plot([], [], "o-", label=plain(f"{label}: no bounce with a measured apex"))
    ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
    ax.set_xlim(-0.5, max(1, int(rows.select(pl.col("bounce").max()).item() or 0)) + 0.5)
    ax.set_yscale("symlog", linthresh=1e-3)
    ax.set_xlabel("bounce number (0: drop)")
    ax.set_ylabel("apex of the lowest point above the surface (m; 0: at rest)")
    ax.set_title(plain(title if legend else f"{title}\n{len(keys)} runs, coloured in sweep order"))
    if legend:
        ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    return save_figure(fig, path)


@styled
def collision_figure(
    states: pl.DataFrame,
    row: dict[str, Any],
    contacts: pl.DataFrame,
    *,
    title: str,
    path: Path,
) -> Path:
    """Positions and velocities along the line of centres, and total momentum, against time.

    Args:
        states: `states_long` of the run.
        row: the collision row (body1, body2, m1_kg, m2_kg, nx, ny, nz, px_before_Ns ..).
        contacts: contact phases of the run (start_t_s, end_t_s), shaded.
    """
    n = np.array([row["nx"], row["ny"], row["nz"]], dtype=float)
    fig, axes = subplots(3, 1, figsize=(9, 8), sharex=True)
    p = None
    for k in ("1", "2"):
        s = states.filter(pl.col("body") == row[f"body{k}"]).sort("t_ns")
        pos = s.select("x", "y", "z").to_numpy() @ n
        vel = s.select("vx", "vy", "vz").to_numpy()
        t = s["t_s"].to_numpy()
        axes[0].plot(*thinned(t, pos), label=plain(row[f"body{k}"]))
        axes[1].plot(*thinned(t, vel @ n), label=plain(row[f"body{k}"]))
        mom = row[f"m{k}_kg"] * vel
        p = mom if p is None else p + mom
    p0 = np.array([row["px_before_Ns"], row["py_before_Ns"], row["pz_before_Ns"]])
    axes[2].plot(*thinned(t, p @ n), label="total momentum along n", color="k")
    axes[2].axhline(p0 @ n, color="tab:red", ls="--", label="before the collision")
    for key, style, lab in (
        ("after_elastic", ":", "elastic"),
        ("after_e", "--", "analytic, measured e"),
    ):
        for k, color in (("1", "tab:blue"), ("2", "tab:orange")):
            if row.get(f"v{k}n_{key}_mps") is not None:
                label = plain(f"{row['body' + k]} {lab}")
                axes[1].axhline(row[f"v{k}n_{key}_mps"], color=color, ls=style, lw=1, label=label)
    for ax in axes:
        _shade_contacts(ax, contacts)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    axes[0].set(ylabel="position along n (m)", title=plain(title))
    axes[1].set_ylabel("velocity along n (m/s)")
    span = max(1e-9, abs(p0 @ n)) * 1e-6
    axes[2].set(ylabel="momentum along n (kg m/s)", xlabel="time (s)")
    axes[2].set_ylim(p0 @ n - max(span, 0.05), p0 @ n + max(span, 0.05))
    return save_figure(fig, path)


@styled
def restitution_figure(
    bounces: pl.DataFrame,
    collisions: pl.DataFrame,
    experiments: dict[str, str],
    *,
    path: Path,
    targets: dict[str, list[float | tuple[Sequence[float], Sequence[float]]]] | None = None,
    tests: Sequence[tuple[str, float, float, float]] = (),
) -> Path:
    """e against impact speed, one colour per experiment (`experiments`: run_id -> name):
    o from velocities and x from apexes of each bounce, squares for two-body collisions (at
    their closing speed), the experiment's target e (`targets`: name -> constants, or e(v)
    curves through their points) dashed, and the drop tests' pass bands (`tests`: name,
    impact speed m/s, lowest and highest e) as black bars."""
    fig, ax = subplots(figsize=(8, 5))
    mine = pl.col("run_id").is_in(list(experiments))
    b = bounces.filter(pl.col("complete") & mine) if bounces.height else bounces
    c = collisions.filter(pl.col("complete") & mine) if collisions.height else collisions
    ids = [*(b["run_id"] if b.height else []), *(c["run_id"] if c.height else [])]
    names = list(dict.fromkeys(experiments[r] for r in ids))
    for i, name in enumerate(names):
        runs = [r for r, e in experiments.items() if e == name]
        color = f"C{i % 10}"
        rows = b.filter(pl.col("run_id").is_in(runs)) if b.height else b
        if rows.height:
            ax.plot(-rows["v_in_mps"], rows["e_velocity"], "o", color=color, label=plain(name))
            apex = rows.filter(pl.col("e_apex").is_not_null())
            ax.plot(-apex["v_in_mps"], apex["e_apex"], "x", ms=9, color=color)
        pairs = c.filter(pl.col("run_id").is_in(runs)) if c.height else c
        if pairs.height:
            speed = pairs["v1n_before_mps"] - pairs["v2n_before_mps"]
            ax.plot(
                speed, pairs["e_velocity"], "s", color=color, label=plain(f"{name} (collisions)")
            )
        for j, target in enumerate((targets or {}).get(name, [])):
            label = None if j else plain(f"{name}: target")
            if isinstance(target, tuple):
                ax.plot(*target, ls="--", lw=1.2, color=color, label=label)
            else:
                ax.axhline(target, ls="--", lw=1, color=color, label=label)
    for test, v, lo, hi in tests:
        words = f"{test} drop test: e {lo:.3f}-{hi:.3f} at {v:.2f} m/s"
        bar = {"color": "k", "lw": 2.5, "ms": 14, "alpha": 0.6, "zorder": 1.5}
        ax.plot([v, v], [lo, hi], "_-", label=plain(words), **bar)
    if names:
        for marker, words in (
            ("o", "e from velocities"),
            ("x", "e from apex heights"),
            ("s", "two-body collision"),
        ):
            ax.plot([], [], marker, color="0.3", label=f"{marker}: {words}")
    ax.set_xlabel("impact (closing) speed of the contact point along the normal (m/s)")
    ax.set(ylabel="coefficient of restitution e", ylim=(0, 1.05))
    ax.set_title("Restitution against impact speed")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    return save_figure(fig, path)


@styled
def collision_study_figure(
    study: pl.DataFrame, param: str, *, title: str, m1: float, m2: float, path: Path
) -> Path:
    """v1', v2' against e: measured runs on the analytic curves; e against the swept parameter.

    Args:
        study: study table (param, e_collision, v1n/v2n before and after).
        param: the swept parameter column.
        m1, m2: the masses (kg) of the analytic curves.
    """
    fig, (ax, ax_p) = subplots(1, 2, figsize=(12, 5))
    rows = study.filter(pl.col("e_collision").is_not_null())
    v1, v2 = rows["v1n_before_mps"][0], rows["v2n_before_mps"][0]
    e = np.linspace(0, 1, 101)
    v1e, v2e = collision_after(m1, m2, v1, v2, e)
    colors = {"1": "tab:blue", "2": "tab:orange"}
    for (k, color), curve in zip(colors.items(), (v1e, v2e), strict=True):
        ax.plot(e, curve, color=color, label=f"analytic v{k}'(e)")
    for k, color in colors.items():
        measured = rows[f"v{k}n_after_mps"]
        ax.plot(rows["e_collision"], measured, "o", color=color, label=f"measured v{k}'")
    ax.plot(
        [1, 1],
        [rows["v1n_after_elastic_mps"][0], rows["v2n_after_elastic_mps"][0]],
        "*",
        ms=14,
        color="k",
        label="elastic answer (e = 1)",
    )
    ax.set(
        xlabel="coefficient of restitution e",
        ylabel="velocity after, along the line of centres (m/s)",
    )
    ax.set_title(
        plain(f"{title}\nm1 = {m1:g} kg, m2 = {m2:g} kg, v1 = {v1:g} m/s, v2 = {v2:g} m/s")
    )
    ax_p.plot(rows[param], rows["e_collision"], "o-", label="measured e")
    ax_p.axhline(1.0, color="k", ls=":", label="elastic (e = 1)")
    ax_p.set(ylim=(0, 1.05), xlabel=plain(param), ylabel="measured e")
    ax_p.set_title(plain(f"e against the swept {param}"))
    for a in (ax, ax_p):
        a.grid(True, alpha=0.3)
        a.legend(fontsize=8)
    return save_figure(fig, path)


@styled
def bounce_study_figure(study: pl.DataFrame, param: str, *, title: str, path: Path) -> Path:
    """First-bounce e against the drop height (m) of the lowest point, or against the swept
    parameter when the study has no drop height; runs without a rebound are marked at e = 0."""
    fig, ax = subplots(figsize=(8, 5))
    x_col = "drop_height_m" if "drop_height_m" in study.columns else param
    rows = study.filter(pl.col(x_col).is_not_null()).sort(x_col)
    x_label = (
        "drop height of the ball's lowest point above the ground (m)"
        if x_col == "drop_height_m"
        else plain(param)
    )
    ax.plot(rows[x_col], rows["e_velocity_first"], "o-", label="e of the first bounce (velocities)")
    if "e_apex_mean" in rows.columns:
        ax.plot(rows[x_col], rows["e_apex_mean"], "x--", ms=9, label="mean e from apexes")
    none = rows.filter(pl.col("e_velocity_first").is_null())
    if none.height:
        ax.plot(
            none[x_col],
            [0.0] * none.height,
            "v",
            ms=9,
            color="tab:red",
            clip_on=False,
            label="no rebound (the ball stays on the ground)",
        )
    shown = ""
    if "first_impact_speed_mps" in rows.columns and x_col == "drop_height_m":
        speeds = rows.select(x_col, "first_impact_speed_mps").drop_nulls()
        if speeds.height > MAX_SPEED_LABELS:  # evenly spaced, the first and last among them
            keep = np.unique(np.linspace(0, speeds.height - 1, MAX_SPEED_LABELS).round())
            speeds = speeds[keep.astype(np.int64).tolist()]
            shown = f", {MAX_SPEED_LABELS} of {rows.height} runs"
        for x, v in speeds.iter_rows():
            ax.annotate(
                f"{v:.3g} m/s",
                (x, 0.0),
                textcoords="offset points",
                xytext=(0, 12),
                ha="center",
                fontsize=8,
                color="0.3",
            )
    ax.set(xlabel=x_label, ylabel="coefficient of restitution e")
    top = float(rows.select(pl.col("e_velocity_first").max()).item() or 0)
    ax.set_ylim(-0.03 * max(0.2, top * 1.5), max(0.2, top * 1.5))
    ax.set_title(plain(f"{title}\n(grey: impact speed at the first contact{shown})"))
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, path)
