"""Calibration figures (matplotlib, Agg) drawn from the point table; no physics is computed here."""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import matplotlib.colors
import numpy as np
import polars as pl
from matplotlib.lines import Line2D

from impactlab.plotting import save_figure, styled, subplots

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.collections import PathCollection
    from matplotlib.colors import Colormap, Normalize

MARKERS = "osD^v<>p*h"
TOLERANCE = 0.005


def _scatter(
    ax: Axes,
    frame: pl.DataFrame,
    y: str,
    *,
    shape_col: str,
    shape_label: Callable[[Any], str],
    norm: Normalize,
    cmap: Colormap,
    dx: float,
) -> PathCollection | None:
    """Points coloured by impact speed, one marker per value of `shape_col`, nudged apart in x."""
    shapes = sorted(frame[shape_col].unique().to_list())
    speeds = sorted(frame["speed_mps"].unique().to_list())
    n = len(speeds) * len(shapes)
    sc: PathCollection | None = None
    for i, value in enumerate(shapes):
        part = frame.filter(pl.col(shape_col) == value)
        slot = np.array([speeds.index(s) * len(shapes) + i for s in part["speed_mps"]])
        x = part["target"].to_numpy() + dx * (slot - (n - 1) / 2) / max(n - 1, 1)
        sc = ax.scatter(
            x,
            part[y].to_numpy(),
            c=part["speed_mps"].to_numpy(),
            cmap=cmap,
            norm=norm,
            marker=MARKERS[i % len(MARKERS)],
            s=22,
            edgecolors="k",
            linewidths=0.3,
            label=shape_label(value),
        )
    return sc


@styled
def calibration_figure(points: pl.DataFrame, *, title: str, path: Path) -> Path:
    """Target vs measured e (top) and the error vs target (bottom), ball-plane and ball-ball.

    Colour: impact (closing) speed; marker: mass (ball-plane) or mass ratio m1/m2 (ball-ball).
    Points of one target are spread a little in x so that they do not hide each other.
    """
    kinds = [
        ("plane", "ball on the floor (gravity)", "m1_kg", lambda m: f"m = {m:g} kg"),
        ("ball", "two balls head-on (zero gravity)", "ratio", lambda r: f"m1/m2 = {r:g}"),
    ]
    frame = points.filter(pl.col("e_measured").is_not_nan()).with_columns(
        (pl.col("m1_kg") / pl.col("m2_kg")).alias("ratio")
    )
    speeds = frame.filter(pl.col("kind").is_in(["plane", "ball"]))["speed_mps"]
    lo, hi = (
        (float(speeds.to_numpy().min()), float(speeds.to_numpy().max()))
        if speeds.len()
        else (1.0, 10.0)
    )
    norm = matplotlib.colors.LogNorm(vmin=lo, vmax=max(hi, lo * 1.01))
    cmap = matplotlib.colormaps.get_cmap("viridis")
    fig, axes = subplots(2, 2, figsize=(13, 9), squeeze=False, layout="constrained")
    sc = None
    for col, (kind, label, shape_col, shape_label) in enumerate(kinds):
        part = frame.filter(pl.col("kind") == kind)
        ax_m, ax_e = axes[0, col], axes[1, col]
        ax_m.plot([0, 1], [0, 1], color="0.5", lw=1, label="measured = target")
        ax_e.axhspan(-TOLERANCE, TOLERANCE, color="tab:green", alpha=0.12, label="±0.005")
        ax_e.axhline(0.0, color="0.5", lw=1)
        if part.height:
            scatter = functools.partial(
                _scatter,
                shape_col=shape_col,
                shape_label=shape_label,
                norm=norm,
                cmap=cmap,
                dx=0.02,
            )
            sc = scatter(ax_m, part, "e_measured") or sc
            scatter(ax_e, part, "error")
            err = part.select(pl.col("error").abs().max()).item()
            ax_m.set_title(f"{label}: {part.height} runs, max |error| {err:.4f}")
        else:
            ax_m.set_title(f"{label}: no runs")
        ax_m.set_xlabel("target e")
        ax_m.set_ylabel("measured e (analysis of the logs)")
        ax_m.set_xlim(0, 1.03)
        ax_m.set_ylim(0, 1.03)
        ax_m.legend(loc="upper left", fontsize=8)
        ax_e.set_xlabel("target e")
        ax_e.set_ylabel("measured - target")
        ax_e.legend(loc="best", fontsize=8)
        for ax in (ax_m, ax_e):
            ax.grid(True, alpha=0.3)
    if sc is not None:
        fig.colorbar(sc, ax=axes.ravel().tolist(), label="impact speed (m/s)", shrink=0.6)
    fig.suptitle(title)
    return save_figure(fig, path, tight_bbox=True)


@styled
def lowspeed_figure(points: pl.DataFrame, curves: pl.DataFrame, *, title: str, path: Path) -> Path:
    """Measured e vs impact speed on the floor (top) and e - target (bottom), with predictions.

    Args:
        points: the point table (rows of kind "lowspeed" are drawn).
        curves: (target, speed_mps, e_pred_release, e_pred_surface), dense in speed.
    """
    low = points.filter(pl.col("kind") == "lowspeed").sort("target", "speed_mps")
    fig, (ax, ax_d) = subplots(
        2, 1, figsize=(9, 9), sharex=True, gridspec_kw={"height_ratios": [3, 2]}
    )
    targets = sorted(low["target"].unique().to_list())
    colors = matplotlib.colormaps.get_cmap("tab10")
    for i, target in enumerate(targets):
        c = colors(i % 10)
        part = low.filter(pl.col("target") == target)
        curve = curves.filter(pl.col("target") == target).sort("speed_mps")
        for axis, offset in ((ax, 0.0), (ax_d, target)):
            axis.axhline(target - offset, color=c, lw=0.8, ls=":")
            if curve.height:
                v = curve["speed_mps"]
                axis.plot(v, curve["e_pred_release"] - offset, color=c, lw=1.2, ls="--")
                axis.plot(v, curve["e_pred_surface"] - offset, color=c, lw=1.6)
            axis.plot(
                part["speed_mps"],
                part["e_measured"] - offset,
                "o",
                color=c,
                mec="k",
                mew=0.4,
                label=f"target {target:g}",
            )
    handles, labels = ax.get_legend_handles_labels()
    style = [
        (Line2D([], [], color="k", lw=1.6), "prediction at the surface (what is measured)"),
        (Line2D([], [], color="k", lw=1.2, ls="--"), "velocity at force release"),
        (Line2D([], [], color="k", lw=0.8, ls=":"), "target (design speed)"),
        (Line2D([], [], color="k", marker="o", ls=""), "measured (analysis of the logs)"),
    ]
    ax.legend(
        handles + [h for h, _ in style], labels + [lab for _, lab in style], fontsize=8, loc="best"
    )
    ax.set_xscale("log")
    ax.set_ylabel("e = v_out / v_in")
    ax.set_title(title)
    ax_d.set_ylabel("e - target")
    ax_d.set_xlabel("impact speed (m/s)")
    for axis in (ax, ax_d):
        axis.grid(True, alpha=0.3, which="both")
    return save_figure(fig, path)


@styled
def bounces_figure(frame: pl.DataFrame, curves: pl.DataFrame, *, title: str, path: Path) -> Path:
    """e - target against impact speed for every bounce of the multi-bounce drops.

    One colour per drop; filled markers are bounces inside the contact's speed range (thick
    segment), open ones below it; the line is the designer's prediction (step emulation, mean
    over contact-onset phases), the band the tolerance.
    """
    fig, ax = subplots(figsize=(10, 6))
    ax.axhspan(-TOLERANCE, TOLERANCE, color="tab:green", alpha=0.12, label="±0.005")
    ax.axhline(0.0, color="0.5", lw=1)
    colors = matplotlib.colormaps.get_cmap("tab10")
    for i, name in enumerate(sorted(frame["name"].unique().to_list())):
        c = colors(i % 10)
        part = frame.filter(pl.col("name") == name).sort("v_in_mps")
        d = part.row(0, named=True)
        target = d["target"]
        curve = curves.filter(pl.col("name") == name).sort("speed_mps")
        if curve.height:
            ax.plot(curve["speed_mps"], curve["e_predicted"] - target, color=c, lw=1.2)
        ax.plot(
            [d["range_lo_mps"], d["range_hi_mps"]], [0.0, 0.0], color=c, lw=5, alpha=0.5,
            solid_capstyle="butt",
        )  # fmt: skip
        label = (
            f"e = {target:g}, r = {d['radius_m']:g} m, {d['mass_kg']:g} kg, "
            f"{d['integrator']}, range {d['range_lo_mps']:.2g}..{d['range_hi_mps']:.2g} m/s"
        )
        for inside, face in ((True, c), (False, "none")):
            sub = part.filter(pl.col("in_range") == inside)
            if sub.height:
                ax.plot(
                    sub["v_in_mps"], sub["error"], "o", color=c, mfc=face, mec=c,
                    label=label if inside else None,
                )  # fmt: skip
    ax.set_xscale("log")
    ax.set_xlabel("impact speed (m/s)")
    ax.set_ylabel("e measured - target (lines: predicted)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="lower right")
    return save_figure(fig, path)
