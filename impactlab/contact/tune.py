"""Tune a user's MJCF model: a calibrated ``<pair>`` for each pair of geoms asked for."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from impactlab.contact.advice import ContactDesign
from impactlab.contact.closed_form import ContactModelError
from impactlab.contact.design import SPEED_FLOOR_MPS, design_contact
from impactlab.contact.pairs import (
    ModelPair,
    check_tuned,
    model_integrator,
    model_pairs,
    pair_element,
)
from impactlab.errors import SpecError
from impactlab.files import atomic_path
from impactlab.mjcf.files import check_not_input
from impactlab.mjcf.load import load_model, parse_mjcf
from impactlab.mjcf.pairs import with_pairs


@dataclass(frozen=True)
class PairRequest:
    """What the user asks of one pair: ``G1/G2[=E][@LO..HI]``."""

    geom1: str
    geom2: str
    restitution: float | None
    speeds: tuple[float, float] | None


@dataclass(frozen=True)
class TunedPair:
    """One pair of the model with its design and the ``<pair>`` element that carries it."""

    pair: ModelPair
    design: ContactDesign
    element: str


@dataclass(frozen=True)
class TunedModel:
    """A model's calibrated pairs; ``ok`` when every pair meets its target."""

    path: Path
    timestep_s: float
    integrator: str
    pairs: tuple[TunedPair, ...]

    @property
    def ok(self) -> bool:
        """Every pair meets its target at the model's timestep."""
        return all(t.design.ok for t in self.pairs)


def tune_model(
    path: Path,
    requests: Sequence[PairRequest],
    *,
    restitution: float | None = None,
    speeds: tuple[float, float] | None = None,
    gravity_mps2: float | None = None,
    max_penetration_m: float | None = None,
    duration_s: float | None = None,
) -> TunedModel:
    """Design every requested pair of a model (nothing written).

    Raises:
        SpecError: the model's file cannot be read, parsed or compiled.
        ContactModelError: a geom name, a target or the speeds are wrong.
    """
    if not requests:
        raise ContactModelError("name the pairs to calibrate: --pair GEOM1/GEOM2=E")
    seen: dict[frozenset[str], PairRequest] = {}
    for r in requests:
        first = seen.setdefault(frozenset((r.geom1, r.geom2)), r)
        if first is not r:
            raise ContactModelError(
                f"--pair {r.geom1}/{r.geom2} names the same pair as --pair "
                f"{first.geom1}/{first.geom2}: give each pair once"
            )
    model = load_model(path)
    timestep_s, integrator = float(model.opt.timestep), model_integrator(model)
    described = model_pairs(model, [(r.geom1, r.geom2) for r in requests])
    tuned = []
    for request, pair in zip(requests, described, strict=True):
        name = f"{pair.geom1}/{pair.geom2}"
        e = request.restitution if request.restitution is not None else restitution
        if e is None:
            raise ContactModelError(f"{name}: give its restitution (--pair {name}=E)")
        rng = request.speeds or speeds or _default_speeds(pair)
        if pair.radius_m is None and max_penetration_m is None and duration_s is None:
            raise ContactModelError(
                f"{name}: neither geom is a sphere, so the default penetration bound (2 % of "
                "the radius) does not apply: give --max-penetration or --duration"
            )
        try:
            design = design_contact(
                e,
                radius_m=pair.radius_m,
                timestep_s=timestep_s,
                speed_range_mps=rng,
                integrator=integrator,
                gravity_mps2=pair.gravity_mps2 if gravity_mps2 is None else gravity_mps2,
                max_penetration_m=max_penetration_m,
                duration_s=duration_s,
            )
        except ContactModelError as exc:
            raise ContactModelError(f"{name}: {exc}") from None
        tuned.append(TunedPair(pair, design, pair_element(pair, design.params)))
    return TunedModel(path, timestep_s, integrator, tuple(tuned))


def _default_speeds(pair: ModelPair) -> tuple[float, float]:
    v1 = pair.first_impact_mps
    if v1 is None:
        raise ContactModelError(
            f"{pair.geom1}/{pair.geom2}: the impact speeds do not follow from the model (only "
            "for a sphere above a static plane under gravity): give --speed LO..HI or "
            f"--pair {pair.geom1}/{pair.geom2}=E@LO..HI"
        )
    return min(SPEED_FLOOR_MPS, v1), v1


def write_tuned(tuned: TunedModel, out: Path) -> Path:
    """Write the model's text with the calibrated pairs to `out` (atomically), checked by
    compiling it with MuJoCo from its new folder.

    Raises:
        ContactModelError: a pair misses its target.
        SpecError: `out` is a file the model reads, or the written model does not compile or
            does not carry the pairs (nothing is left behind then).
    """
    if not tuned.ok:
        raise ContactModelError("a pair misses its target: nothing written")
    check_not_input(out, tuned.path, parse_mjcf(tuned.path))
    try:
        raw = tuned.path.read_bytes()
    except OSError as exc:
        raise SpecError(str(tuned.path), "", f"cannot read: {exc.strerror or exc}") from None
    pairs = [(t.pair.geom1, t.pair.geom2, t.element) for t in tuned.pairs]
    data = with_pairs(raw, pairs, str(tuned.path))
    with atomic_path(out) as tmp:
        tmp.write_bytes(data)
        check_tuned(tmp, [(t.pair, t.design.params) for t in tuned.pairs])
    return out
