"""The physics of a recording against its golden log's, from the analysis' own tables."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import polars as pl

from impactlab.show import plain
from impactlab.tools.compare import differences, flatten


@dataclass(frozen=True)
class PhysicsTolerance:
    """How far a recording's measured physics may move from its golden log's: `e` absolute
    (the contact model's own guarantee, docs/contact-model.md), velocities (m/s) and apex
    heights (m) `|a - b| <= abs + rel * max(|a|, |b|)`, energies relative to the golden run's
    initial energy, impact times absolute (s)."""

    e: float = 0.005
    speed_abs: float = 0.001
    speed_rel: float = 0.005
    height_abs: float = 0.001
    height_rel: float = 0.005
    energy_rel: float = 0.005
    time_s: float = 0.001

    def bounds(self, kind: str, scale: float) -> tuple[float, float]:
        """(atol, rtol) of a kind of quantity; `scale`: the golden initial energy, J."""
        energy = (self.energy_rel * scale, 0.0) if scale else (0.0, self.energy_rel)
        return {
            "e": (self.e, 0.0),
            "speed": (self.speed_abs, self.speed_rel),
            "height": (self.height_abs, self.height_rel),
            "energy": energy,
            "time": (self.time_s, 0.0),
        }[kind]


# column: (label, unit, kind)
ENERGY = {
    "energy_initial_J": ("initial energy", "J", "energy"),
    "energy_final_J": ("final energy", "J", "energy"),
    "contact_loss_sum_J": ("energy lost in contacts", "J", "energy"),
}
BOUNCES = {
    "e_velocity": ("e", "", "e"),
    "v_in_mps": ("v in", "m/s", "speed"),
    "v_out_mps": ("v out", "m/s", "speed"),
    "apex_m": ("apex", "m", "height"),
    "impact_t_s": ("impact at", "s", "time"),
}
COLLISIONS = {
    "e_velocity": ("e", "", "e"),
    "v1n_before_mps": ("v1", "m/s", "speed"),
    "v2n_before_mps": ("v2", "m/s", "speed"),
    "v1n_after_mps": ("v1'", "m/s", "speed"),
    "v2n_after_mps": ("v2'", "m/s", "speed"),
    "ke_loss_J": ("kinetic energy lost", "J", "energy"),
    "impact_t_s": ("impact at", "s", "time"),
}


@dataclass
class PhysicsComparison:
    """What differs, one sentence each (golden -> new), and how many quantities were compared."""

    differences: list[str] = field(default_factory=list)
    compared: int = 0

    @property
    def equal(self) -> bool:
        return not self.differences


def compare_physics(
    golden: Any, new: Any, tolerance: PhysicsTolerance | None = None
) -> PhysicsComparison:
    """Compare two analyses of one run each (`impactlab.analyze.AnalysisResult`)."""
    tol, out = tolerance or PhysicsTolerance(), PhysicsComparison()
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
    energy = pl.lit("energy budget").alias("group"), pl.lit(0, pl.Int64).alias("k")
    pairs = [
        ((golden.runs.with_columns(*energy), new.runs.with_columns(*energy)), ENERGY, ""),
        ((_bounces(golden.bounces), _bounces(new.bounces)), BOUNCES, "bounce"),
        ((_collisions(golden.collisions), _collisions(new.collisions)), COLLISIONS, "collision"),
    ]
    for frames, quantities, noun in pairs:
        _compare(out, frames, quantities, tol, scale, noun)
    return out


def _bounces(frame: pl.DataFrame) -> pl.DataFrame:
    """Real bounces (an impact time), numbered per body and surface; named by the body, and
    the surface too when the body bounces on several."""
    if not frame.height or "impact_t_s" not in frame.columns:
        return pl.DataFrame(schema={"group": pl.String, "k": pl.Int64})
    real = frame.filter(pl.col("impact_t_s").is_not_null()).sort("body", "surface", "bounce")
    several = pl.col("surface").n_unique().over("body") > 1
    name = pl.when(several).then(pl.format("{} on {}", "body", "surface")).otherwise("body")
    return real.with_columns(group=name, k=pl.int_range(1, pl.len() + 1).over("body", "surface"))


def _collisions(frame: pl.DataFrame) -> pl.DataFrame:
    """Collisions numbered per pair of bodies."""
    if not frame.height:
        return pl.DataFrame(schema={"group": pl.String, "k": pl.Int64})
    frame = frame.sort("body1", "body2", "collision")
    k = pl.int_range(1, pl.len() + 1).over("body1", "body2")
    return frame.with_columns(group=pl.format("{}/{}", "body1", "body2"), k=k)


def _compare(
    out: PhysicsComparison,
    frames: tuple[pl.DataFrame, pl.DataFrame],
    quantities: dict[str, tuple[str, str, str]],
    tol: PhysicsTolerance,
    scale: float,
    noun: str,
) -> None:
    """Each group's count (`noun`s), then each of its rows' quantities, golden -> new."""
    columns = {c: tol.bounds(kind, scale) for c, (_, _, kind) in quantities.items()}
    golden, new = (
        f.with_columns(
            pl.lit(None, pl.Float64).alias(c) for c in columns if c not in f.columns
        ).select("group", "k", *columns)
        for f in frames
    )
    counts = [dict(f.group_by("group").len().iter_rows()) for f in (golden, new)]
    groups = sorted(counts[0].keys() | counts[1].keys())
    joined = differences(golden, new, ["group", "k"], columns)
    for group in groups:
        a, b = counts[0].get(group, 0), counts[1].get(group, 0)
        out.compared += 1 if noun else 0
        if noun and a != b:
            out.differences.append(f"{noun}s of {plain(group)}: {a} -> {b}")
        rows = joined.filter(pl.col("group") == group)
        for row in rows.iter_rows(named=True):
            where = {
                "bounce": f"bounce {row['k']} of {plain(group)}",
                "collision": f"collision {plain(group)}"
                + (f" #{row['k']}" if max(a, b) > 1 else ""),
            }.get(noun, plain(group))
            for column, (label, unit, _) in quantities.items():
                out.compared += 1
                if row[f"{column}_beyond"]:
                    line = _line(label, unit, row[column], row[f"{column}_b"], row[f"{column}_tol"])
                    out.differences.append(f"{where}: {line}")


def _line(label: str, unit: str, a: Any, b: Any, allowed: float) -> str:
    """`e 0.800 -> 0.792 (tolerance 0.005)`, or `e not measured -> 0.8`."""
    unit = f" {unit}" if unit else ""
    missing = [v is None or (isinstance(v, float) and math.isnan(v)) for v in (a, b)]
    if any(missing):
        shown = [
            "not measured" if m else f"{v:.4g}{unit}" for v, m in zip((a, b), missing, strict=True)
        ]
        return f"{label} {shown[0]} -> {shown[1]}"
    digits = min(max(2, math.ceil(-math.log10(allowed))), 9) if allowed > 0 else 6
    return f"{label} {a:.{digits}f} -> {b:.{digits}f}{unit} (tolerance {allowed:.2g}{unit})"


def spec_changes(golden: dict[str, Any], new: dict[str, Any]) -> list[str]:
    """The fields of two spec documents that differ: `contact.restitution: 0.8 -> 0.81`."""
    fa, fb = flatten(golden), flatten(new)
    return [
        f"{plain(k)}: {plain(fa.get(k, '(none)'))} -> {plain(fb.get(k, '(none)'))}"
        for k in sorted(fa.keys() | fb.keys())
        if fa.get(k) != fb.get(k)
    ]
