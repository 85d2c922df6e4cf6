"""The physics of a recording against its golden log's, from the analysis' own tables.

Both logs are analyzed (`impactlab.analyze`, tables only); what is compared is what the
analysis measures, each difference said in physical terms:

- how the run ended: its outcome and reason (`run ended: apex after bounce 2 -> time limit`);
- the energy budget: initial and final energy, energy lost in contacts;
- the bounces of each body on each surface: how many (`bounces of ball: 3 -> 2`), then per
  bounce its e, impact and rebound velocities, apex and impact time (`bounce 2 of ball: e
  0.800 -> 0.792 (tolerance 0.005)`);
- the collisions of each pair of bodies: how many, then per collision its e, the normal
  velocities before and after (`collision ball1/ball2: v1' -2.33 -> -2.10 m/s`) and the
  kinetic energy it took.

Numbers agree within `PhysicsTolerance` (absolute for e and times, absolute plus relative for
velocities, heights and energies). Names from the logs are made printable (`show.plain`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import polars as pl

from impactlab.show import plain


@dataclass(frozen=True)
class PhysicsTolerance:
    """How far a recording's measured physics may move from its golden log's.

    Attributes:
        e: coefficient of restitution (bounces and collisions), absolute; the contact
            model's own guarantee is 0.005 (docs/contact-model.md).
        speed_abs, speed_rel: velocities, m/s: |a - b| <= speed_abs + speed_rel * max(|a|, |b|).
        height_abs, height_rel: apex heights, m, the same way.
        energy_rel: energies, relative to the golden run's initial energy (J).
        time_s: impact times, s.
    """

    e: float = 0.005
    speed_abs: float = 0.001
    speed_rel: float = 0.005
    height_abs: float = 0.001
    height_rel: float = 0.005
    energy_rel: float = 0.005
    time_s: float = 0.001


@dataclass(frozen=True)
class Quantity:
    """A measured column: its label in a sentence, unit and tolerance kind."""

    column: str
    label: str
    unit: str
    kind: str  # "e", "speed", "height", "energy", "time"


BOUNCE_QUANTITIES = (
    Quantity("e_velocity", "e", "", "e"),
    Quantity("v_in_mps", "v in", "m/s", "speed"),
    Quantity("v_out_mps", "v out", "m/s", "speed"),
    Quantity("apex_m", "apex", "m", "height"),
    Quantity("impact_t_s", "impact at", "s", "time"),
)
COLLISION_QUANTITIES = (
    Quantity("e_velocity", "e", "", "e"),
    Quantity("v1n_before_mps", "v1", "m/s", "speed"),
    Quantity("v2n_before_mps", "v2", "m/s", "speed"),
    Quantity("v1n_after_mps", "v1'", "m/s", "speed"),
    Quantity("v2n_after_mps", "v2'", "m/s", "speed"),
    Quantity("ke_loss_J", "kinetic energy lost", "J", "energy"),
    Quantity("impact_t_s", "impact at", "s", "time"),
)
ENERGY_QUANTITIES = (
    Quantity("energy_initial_J", "initial energy", "J", "energy"),
    Quantity("energy_final_J", "final energy", "J", "energy"),
    Quantity("contact_loss_sum_J", "energy lost in contacts", "J", "energy"),
)


@dataclass
class PhysicsComparison:
    """What differs between the golden log's physics and a new recording's.

    Attributes:
        differences: one sentence per difference beyond its tolerance, golden -> new.
        compared: how many quantities were compared.
    """

    differences: list[str] = field(default_factory=list)
    compared: int = 0

    @property
    def equal(self) -> bool:
        return not self.differences


def compare_physics(
    golden: Any, new: Any, tolerance: PhysicsTolerance | None = None
) -> PhysicsComparison:
    """Compare two analyses of one run each (`impactlab.analyze.AnalysisResult`)."""
    tol = tolerance or PhysicsTolerance()
    out = PhysicsComparison()
    for result, side in ((golden, "golden log"), (new, "new recording")):
        for path, why in result.failed:
            out.differences.append(f"the {side} could not be analyzed: {plain(path)}: {plain(why)}")
    if golden.runs.height != 1 or new.runs.height != 1:
        out.differences.append(
            f"runs analyzed: golden {golden.runs.height}, new {new.runs.height} (need one each)"
        )
        return out
    g, n = golden.runs.row(0, named=True), new.runs.row(0, named=True)
    for key, label in (("outcome", "outcome"), ("reason", "run ended")):
        out.compared += 1
        if g.get(key) != n.get(key):
            out.differences.append(f"{label}: {plain(g.get(key))} -> {plain(n.get(key))}")
    scale = abs(g.get("energy_initial_J") or 0.0)
    for q in ENERGY_QUANTITIES:
        out.compared += 1
        line = _differ(q, g.get(q.column), n.get(q.column), tol, scale)
        if line:
            out.differences.append(f"energy budget: {line}")
    for label, a, b in _events(golden.bounces, new.bounces, _bounce_groups):
        _compare_events(out, label, a, b, BOUNCE_QUANTITIES, tol, scale, "bounce")
    for label, a, b in _events(golden.collisions, new.collisions, _collision_groups):
        _compare_events(out, label, a, b, COLLISION_QUANTITIES, tol, scale, "collision")
    return out


def _bounce_groups(frame: pl.DataFrame) -> dict[str, pl.DataFrame]:
    """Real bounces (an impact time) per body and surface, by bounce number."""
    if not frame.height or "impact_t_s" not in frame.columns:
        return {}
    real = frame.filter(pl.col("impact_t_s").is_not_null()).sort("body", "surface", "bounce")
    surfaces = real.group_by("body").agg(pl.col("surface").n_unique())
    several = {b for b, k in surfaces.iter_rows() if k > 1}
    out = {}
    for (body, surface), rows in real.group_by(["body", "surface"], maintain_order=True):
        name = plain(body) + (f" on {plain(surface)}" if body in several else "")
        out[name] = rows
    return out


def _collision_groups(frame: pl.DataFrame) -> dict[str, pl.DataFrame]:
    """Collisions per pair of bodies, in order."""
    if not frame.height:
        return {}
    frame = frame.sort("body1", "body2", "collision")
    return {
        f"{plain(b1)}/{plain(b2)}": rows
        for (b1, b2), rows in frame.group_by(["body1", "body2"], maintain_order=True)
    }


Groups = Callable[[pl.DataFrame], dict[str, pl.DataFrame]]


def _events(
    golden: pl.DataFrame, new: pl.DataFrame, groups: Groups
) -> Iterator[tuple[str, Any, Any]]:
    a, b = groups(golden), groups(new)
    for name in sorted(a.keys() | b.keys()):
        yield name, a.get(name), b.get(name)


def _compare_events(
    out: PhysicsComparison,
    name: str,
    a: pl.DataFrame | None,
    b: pl.DataFrame | None,
    quantities: tuple[Quantity, ...],
    tol: PhysicsTolerance,
    scale: float,
    noun: str,
) -> None:
    rows_a = a.rows(named=True) if a is not None else []
    rows_b = b.rows(named=True) if b is not None else []
    out.compared += 1
    if len(rows_a) != len(rows_b):
        out.differences.append(f"{noun}s of {name}: {len(rows_a)} -> {len(rows_b)}")
    several = max(len(rows_a), len(rows_b)) > 1
    for k, (ra, rb) in enumerate(zip(rows_a, rows_b, strict=False), start=1):
        where = f"{noun} {k} of {name}" if noun == "bounce" else f"{noun} {name}"
        if noun == "collision" and several:
            where += f" #{k}"
        for q in quantities:
            out.compared += 1
            line = _differ(q, ra.get(q.column), rb.get(q.column), tol, scale)
            if line:
                out.differences.append(f"{where}: {line}")


def _differ(q: Quantity, a: Any, b: Any, tol: PhysicsTolerance, scale: float) -> str | None:
    """`e 0.800 -> 0.792 (tolerance 0.005)` when a and b differ beyond the tolerance."""
    missing_a, missing_b = _missing(a), _missing(b)
    if missing_a and missing_b:
        return None
    unit = f" {q.unit}" if q.unit else ""
    if missing_a or missing_b:
        shown = [
            ("not measured" if m else f"{v:.4g}{unit}") for v, m in ((a, missing_a), (b, missing_b))
        ]
        return f"{q.label} {shown[0]} -> {shown[1]}"
    a, b = float(a), float(b)
    allowed = _allowed(q.kind, a, b, tol, scale)
    if abs(a - b) <= allowed:
        return None
    digits = max(2, math.ceil(-math.log10(allowed))) if allowed > 0 else 6
    digits = min(digits, 9)
    return f"{q.label} {a:.{digits}f} -> {b:.{digits}f}{unit} (tolerance {allowed:.2g}{unit})"


def _allowed(kind: str, a: float, b: float, tol: PhysicsTolerance, scale: float) -> float:
    big = max(abs(a), abs(b))
    if kind == "e":
        return tol.e
    if kind == "speed":
        return tol.speed_abs + tol.speed_rel * big
    if kind == "height":
        return tol.height_abs + tol.height_rel * big
    if kind == "energy":
        return tol.energy_rel * (scale or big)
    return tol.time_s


def _missing(value: Any) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


def spec_changes(golden: dict[str, Any], new: dict[str, Any]) -> list[str]:
    """The fields of two spec documents that differ: `contact.restitution: 0.8 -> 0.81`."""
    fa, fb = _flatten(golden), _flatten(new)
    return [
        f"{plain(k)}: {plain(fa.get(k, '(none)'))} -> {plain(fb.get(k, '(none)'))}"
        for k in sorted(fa.keys() | fb.keys())
        if fa.get(k) != fb.get(k)
    ]


def _flatten(value: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(value, dict):
        out: dict[str, Any] = {}
        for k, v in value.items():
            out |= _flatten(v, f"{prefix}.{k}" if prefix else str(k))
        return out
    return {prefix: value}
