"""A contact design for people (lines of text) and for scripts (a JSON-ready dict)."""

from __future__ import annotations

import dataclasses
import decimal
import itertools
import math
from typing import Any

import numpy as np

from impactlab.contact.advice import ContactDesign, Prediction, significant
from impactlab.contact.curvefit import CURVE_TOLERANCE, rest_sink_m
from impactlab.contact.params import ContactParams
from impactlab.contact.table import RESTITUTION_TOLERANCE


def _range(p: ContactParams) -> str:
    lo, hi = p.speed_range_mps
    return f"{lo:.4g} m/s" if lo == hi else f"{lo:.4g}..{hi:.4g} m/s"


def _pen(p: ContactParams, radius_m: float | None) -> str:
    text = f"{p.max_penetration_m * 1e3:.3g} mm at {p.speed_range_mps[1]:.4g} m/s"
    return text + (f" ({p.max_penetration_m / radius_m:.2%} of the radius)" if radius_m else "")


def _e_line(pred: Prediction, target: float) -> str:
    lo, hi = pred.e_range()
    means = [m for m, inside in zip(pred.mean, pred.in_range, strict=True) if inside]
    return (
        f"{lo:.4f} .. {hi:.4f} (worst |e - {target:g}| = {pred.worst_error(target):.4f}; "
        f"mean over step phases {min(means):.4f} .. {max(means):.4f})"
    )


def round_up(x: float) -> float:
    """x rounded up to three significant digits (a bound the user can type)."""
    return significant(x, decimal.ROUND_CEILING)


def design_lines(
    design: ContactDesign,
    *,
    radius_m: float | None,
    pair_element: str | None = None,
) -> list[str]:
    """What ``impactlab contact`` prints for one designed contact."""
    p = design.params
    k = p.stiffness
    lines = [
        f"contact for e = {p.restitution:g} over impact speeds {_range(p)}: timestep "
        f"{p.timestep_s:g} s ({p.integrator}), gravity along the normal {p.gravity_mps2:g} m/s^2",
        f"  solref    {p.solref[0]!r} {p.solref[1]!r}   (stiffness {k:.6g} 1/s^2, damping "
        f"{p.damping:.6g} 1/s, zeta {p.zeta:.5f}; direct form, mass independent)",
        "  solimp    " + " ".join(f"{x:g}" for x in p.solimp),
    ]
    pred = design.prediction
    if design.ok:
        lines.append(f"  e over {_range(p)}: {_e_line(pred, p.restitution)}")
        below = [
            f"{m:.4f} at {v:.3g} m/s"
            for v, m, inside in zip(pred.speeds_mps, pred.mean, pred.in_range, strict=True)
            if not inside
        ]
        if below:
            lines.append("  below the range, gravity lowers e: " + ", ".join(below))
        lines += [
            f"  worst penetration {_pen(p, radius_m)}",
            f"  contact duration {p.duration_s * 1e3:.4g} ms = {p.steps_per_contact:.1f} steps",
            "  " + (pair_element or p.mjcf_pair("GEOM1", "GEOM2")),
        ]
        return lines
    if design.timestep_max_s is None:
        lines.append(f"  NOT MET at timestep {p.timestep_s:g} s: {design.problem}")
    else:
        steps = math.ceil(p.duration_s / design.timestep_max_s)
        lines += [
            f"  NOT MET at timestep {p.timestep_s:g} s: {p.steps_per_contact:.3g} steps per "
            f"contact of {p.duration_s * 1e3:.4g} ms",
            f"  the target needs timestep <= {design.timestep_max_s:.3g} s ({steps} steps per "
            f"contact, stiffness {k:.4g}), or a softer contact or a narrower speed range",
        ]
    if design.best is not None and design.best_prediction is not None:
        b = design.best
        lines.append(
            f"  best at {p.timestep_s:g} s: e {_e_line(design.best_prediction, p.restitution)}, "
            f"penetration {_pen(b, radius_m)}, stiffness {b.stiffness:.4g}"
        )
        if radius_m and b.max_penetration_m > 0.5 * radius_m:
            lines.append("  note: that penetration is more than half the radius: not usable")
    if design.softer is not None:
        pen = round_up(design.softer.max_penetration_m)
        lines.append(
            f"  a softer contact meets e within {RESTITUTION_TOLERANCE} at {p.timestep_s:g} s "
            f"if the penetration may reach {pen:g} m: --max-penetration {pen:g}"
        )
    lines += [f"  note: {n}" for n in design.notes]
    return lines


def _prediction(pred: Prediction, target: float) -> dict[str, Any]:
    lo, hi = pred.e_range()
    return {
        **dataclasses.asdict(pred),
        "e_lowest_in_range": lo,
        "e_highest_in_range": hi,
        "worst_error_in_range": pred.worst_error(target),
    }


def params_dict(p: ContactParams) -> dict[str, Any]:
    """The parameters, what they were designed for and the designer's own (table)
    predictions."""
    return {**dataclasses.asdict(p), "steps_per_contact": p.steps_per_contact}


def design_dict(
    design: ContactDesign,
    *,
    pair_element: str | None = None,
) -> dict[str, Any]:
    """The design as JSON-ready data (``impactlab contact --json``)."""
    p = design.params
    out: dict[str, Any] = {
        "ok": design.ok,
        "problem": design.problem,
        "tolerance": RESTITUTION_TOLERANCE,
        **params_dict(p),
        "predicted": _prediction(design.prediction, p.restitution),
        "mjcf_pair": pair_element or p.mjcf_pair("GEOM1", "GEOM2"),
        "timestep_max_s": design.timestep_max_s,
        "best": None,
        "softer": None,
        "notes": list(design.notes),
    }
    if design.best is not None:
        out["best"] = params_dict(design.best)
        if design.best_prediction is not None:
            out["best"]["predicted"] = _prediction(design.best_prediction, p.restitution)
    if design.softer is not None:
        out["softer"] = params_dict(design.softer)
        out["softer"]["max_penetration_m_to_ask"] = round_up(design.softer.max_penetration_m)
    return out


def curve_lines(design: ContactDesign, *, radius_m: float | None) -> list[str]:
    """What ``impactlab contact`` prints for a contact designed for a target e(v)."""
    p, pred = design.params, design.prediction
    assert p.curve is not None and p.reference_speed_mps is not None
    targets = p.curve.at(pred.speeds_mps)
    worst = pred.worst_error(p.curve)
    status = "met" if design.ok else "NOT MET"
    lines = [
        f"contact for a target e(v) over impact speeds {_range(p)}: timestep {p.timestep_s:g} s "
        f"({p.integrator}), gravity along the normal {p.gravity_mps2:g} m/s^2",
        f"  solref    {p.solref[0]!r} {p.solref[1]!r}   (stiffness {p.stiffness:.6g} 1/s^2, "
        f"damping {p.damping:.6g} 1/s, zeta {p.zeta:.5f}; direct form, mass independent)",
        "  solimp    " + " ".join(f"{x:.6g}" for x in p.solimp) + "   (impedance rising with "
        "penetration)",
        "  speed m/s   target e   e (mean over step phases)   lowest .. highest",
    ]
    speeds = np.array(pred.speeds_mps)
    errors = np.maximum(
        np.abs(np.array(pred.lowest) - targets), np.abs(np.array(pred.highest) - targets)
    )
    points = np.isin(speeds, p.curve.speed_mps)
    shown = set(np.flatnonzero(points))
    for a, b in itertools.pairwise(np.flatnonzero(points)):  # the worst speed between points
        if b > a + 1:
            shown.add(a + 1 + int(np.argmax(errors[a + 1 : b])))
    for i in sorted(shown):
        mark = "point" if points[i] else "worst between"
        lines.append(
            f"  {speeds[i]:9.4g}   {targets[i]:8.4f}   {pred.mean[i]:8.4f}   "
            f"{pred.lowest[i]:.4f} .. {pred.highest[i]:.4f}   ({mark})"
        )
    lines += [
        f"  worst |e - target| {worst:.4f} over {_range(p)}, at and between the points "
        f"({status}: the tolerance for a curve is {CURVE_TOLERANCE})",
        f"  worst penetration {_pen(p, radius_m)}",
        f"  contact time {p.duration_s * 1e3:.4g} ms at {p.reference_speed_mps:.4g} m/s "
        f"= {p.steps_per_contact:.1f} steps",
        f"  a ball at rest sinks {_sink(p, radius_m)}",
    ]
    if design.ok:
        return [*lines, "  " + p.mjcf_pair("GEOM1", "GEOM2")]
    return [*lines, f"  NOT MET: {design.problem}"]


def _sink(p: ContactParams, radius_m: float | None) -> str:
    sink = rest_sink_m(p)
    text = f"{sink * 1e3:.3g} mm"
    return text + (f" ({sink / radius_m:.2%} of the radius)" if radius_m else "")


def curve_dict(design: ContactDesign, *, radius_m: float | None) -> dict[str, Any]:
    """A curve's design as JSON-ready data (``impactlab contact --json``)."""
    p = design.params
    assert p.curve is not None
    pred = design.prediction
    sink = rest_sink_m(p)
    return {
        "ok": design.ok,
        "problem": design.problem,
        "tolerance": CURVE_TOLERANCE,
        **params_dict(p),
        "predicted": {
            **dataclasses.asdict(pred),
            "target": [float(x) for x in p.curve.at(pred.speeds_mps)],
            "worst_error_in_range": pred.worst_error(p.curve),
        },
        "rest_sink_m": sink,
        "rest_sink_fraction_of_radius": sink / radius_m if radius_m else None,
        "mjcf_pair": p.mjcf_pair("GEOM1", "GEOM2"),
        "timestep_max_s": design.timestep_max_s,
    }
