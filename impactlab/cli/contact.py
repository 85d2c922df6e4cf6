"""`impactlab contact`: MuJoCo contact parameters for a target restitution, alone or in a model.

Exit codes: 0 the target is met, 1 it is not at this timestep or a curve is beyond reach (the
advice or the nearest curve is printed), 2 bad input.
"""

from __future__ import annotations

import argparse
import math
import re
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from impactlab.contact import RestitutionCurve
    from impactlab.contact.tune import PairRequest

INTEGRATORS = ("Euler", "implicit", "implicitfast", "RK4")  # checked against contact by a test
SOURCE = "impactlab contact"


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the `contact` subcommand."""
    p = sub.add_parser(
        "contact",
        help="solref/solimp for a target restitution, or a target e(v), over a range of "
        "impact speeds (any MJCF)",
        description="Design a MuJoCo contact (direct-form solref, constant solimp) whose "
        "coefficient of restitution is within 0.005 of a target at every impact speed of a "
        "range, for a timestep and integrator; print the parameters, the predicted e, the "
        "penetration, the steps per contact and an MJCF <pair>. A target e(v) (measured "
        "points, or --law) gets a rising solimp fitted within 0.01 at and between the points, "
        "with the contact time and the resting sink. With MODEL.xml and --pair, "
        "take the timestep, integrator, radii and gravity from the model and write it back "
        "with calibrated <pair> elements (-o), everything else as it was. Exit 0 when the "
        "target is met, 1 when the timestep is too coarse (with what would work), 2 on bad "
        "input. See docs/contact-model.md.",
    )
    p.add_argument("model", nargs="?", type=Path, metavar="MODEL.xml", help="an MJCF model")
    p.add_argument(
        "--restitution",
        type=restitution,
        metavar="E|V:E,...",
        help="target e (0.1354..1), or a target e(v): measured points SPEED:E,... (m/s, "
        "ascending; e is promised between the points, within 0.01)",
    )
    p.add_argument(
        "--law",
        type=law,
        metavar="C1,C2",
        help="a target e(v) = 1 - C1 v^(1/5) + C2 v^(2/5) (Ramirez et al. 1999, v in m/s) "
        "over --speed LO..HI, instead of --restitution",
    )
    p.add_argument(
        "--reference-speed",
        type=number,
        metavar="V",
        help="for a target e(v): the impact speed in m/s at which --duration applies "
        "(default the top speed)",
    )
    p.add_argument(
        "--radius", type=number, metavar="M", help="smaller ball radius in m (without a model)"
    )
    p.add_argument(
        "--speed", type=speeds, metavar="LO..HI", help="normal impact speeds in m/s, or one speed"
    )
    p.add_argument("--timestep", type=number, metavar="S", help="timestep in s (without a model)")
    p.add_argument(
        "--integrator", choices=INTEGRATORS, help="MuJoCo integrator (default Euler; no model)"
    )
    p.add_argument(
        "--gravity",
        type=number,
        metavar="G",
        help="gravity along the contact normal in m/s^2 (default 9.81, or from the model; "
        "0 for two free bodies or zero gravity)",
    )
    p.add_argument(
        "--max-penetration", type=number, metavar="M", help="max penetration in m at the top speed"
    )
    p.add_argument("--duration", type=number, metavar="S", help="contact duration in s (instead)")
    p.add_argument(
        "--pair",
        type=pair,
        action="append",
        default=[],
        metavar="G1/G2=E[@LO..HI]",
        help="a pair of the model's geoms, its target e and impact speeds (repeatable)",
    )
    p.add_argument(
        "-o",
        "--out",
        type=Path,
        metavar="TUNED.xml",
        help="write the tuned model (never the model or a file it includes or reads)",
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Design (and write); 0 when every target is met, 1 when not."""
    from impactlab.contact import ContactModelError
    from impactlab.errors import SpecError

    try:
        return _model(args) if args.model is not None else _alone(args)
    except ContactModelError as exc:
        raise SpecError(str(args.model) if args.model else SOURCE, "", str(exc)) from None


def _emit(args: argparse.Namespace, lines: list[str], document: object) -> None:
    import json

    print(json.dumps(document, indent=2, allow_nan=False) if args.json else "\n".join(lines))


def _alone(args: argparse.Namespace) -> int:
    from impactlab.contact import ContactModelError, RestitutionCurve, design_contact
    from impactlab.contact.summary import design_dict, design_lines

    for flag, given in (("--pair", args.pair), ("-o", args.out)):
        if given:
            raise ContactModelError(f"{flag} needs an MJCF model: impactlab contact MODEL.xml")
    if args.law is not None or isinstance(args.restitution, RestitutionCurve):
        return _curve(args)
    if args.reference_speed is not None:
        raise ContactModelError("--reference-speed is for a target e(v) (a table or --law)")
    if args.speed is None:
        raise ContactModelError("--speed LO..HI is required (normal impact speeds in m/s)")
    for flag in ("restitution", "timestep"):
        if getattr(args, flag) is None:
            raise ContactModelError(f"--{flag} is required")
    design = design_contact(
        args.restitution,
        radius_m=args.radius,
        timestep_s=args.timestep,
        speed_range_mps=args.speed,
        integrator=args.integrator or "Euler",
        gravity_mps2=9.81 if args.gravity is None else args.gravity,
        max_penetration_m=args.max_penetration,
        duration_s=args.duration,
    )
    _emit(args, design_lines(design, radius_m=args.radius), design_dict(design))
    return 0 if design.ok else 1


def _curve(args: argparse.Namespace) -> int:
    """A target e(v): 0 when the fit is within the tolerance, 1 (the nearest curve printed)
    when not."""
    from impactlab.contact import ContactModelError, CurveOutOfReach, design_contact
    from impactlab.contact.curve import ramirez_curve
    from impactlab.contact.summary import curve_dict, curve_lines

    if args.law is not None:
        if args.restitution is not None:
            raise ContactModelError("give --restitution or --law, not both")
        if args.speed is None:
            raise ContactModelError("--law needs --speed LO..HI (normal impact speeds in m/s)")
        target = ramirez_curve(args.law[0], args.law[1], args.speed)
    else:
        target = args.restitution
    if args.timestep is None:
        raise ContactModelError("--timestep is required")
    try:
        design = design_contact(
            target,
            radius_m=args.radius,
            timestep_s=args.timestep,
            speed_range_mps=None if args.law is not None else args.speed,
            integrator=args.integrator or "Euler",
            gravity_mps2=9.81 if args.gravity is None else args.gravity,
            max_penetration_m=args.max_penetration,
            duration_s=args.duration,
            reference_speed_mps=args.reference_speed,
        )
    except CurveOutOfReach as exc:
        design = exc.design
    _emit(args, curve_lines(design, radius_m=args.radius), curve_dict(design, radius_m=args.radius))
    return 0 if design.ok else 1


def _model(args: argparse.Namespace) -> int:
    from impactlab.contact import ContactModelError, RestitutionCurve
    from impactlab.contact.summary import design_dict, design_lines
    from impactlab.contact.tune import tune_model, write_tuned
    from impactlab.files import check_writable
    from impactlab.mjcf.files import check_not_input
    from impactlab.mjcf.load import parse_mjcf

    if args.law is not None or isinstance(args.restitution, RestitutionCurve):
        raise ContactModelError(
            "a target e(v) is designed without a model: impactlab contact --restitution "
            "V:E,... --radius M --timestep S"
        )
    if args.reference_speed is not None:
        raise ContactModelError("--reference-speed is for a target e(v) (a table or --law)")
    for flag in ("radius", "timestep", "integrator"):
        if getattr(args, flag) is not None:
            raise ContactModelError(
                f"--{flag} comes from the model (its geoms and <option>); edit the model to "
                "change it"
            )
    if args.out is not None:
        if args.out.is_dir():
            raise ContactModelError(f"-o {args.out} is a folder: give the tuned model's file name")
        check_writable(args.out.resolve().parent)
        check_not_input(args.out, args.model, parse_mjcf(args.model))
    tuned = tune_model(
        args.model,
        args.pair,
        restitution=args.restitution,
        speeds=args.speed,
        gravity_mps2=args.gravity,
        max_penetration_m=args.max_penetration,
        duration_s=args.duration,
    )
    lines = [f"{args.model}: timestep {tuned.timestep_s:g} s, integrator {tuned.integrator}"]
    for t in tuned.pairs:
        lines += design_lines(t.design, radius_m=t.pair.radius_m, pair_element=t.element)
        lines += [f"  note: {n}" for n in t.pair.notes]
    written = None
    if args.out is not None and tuned.ok:
        written = str(write_tuned(tuned, args.out))
        lines.append(f"wrote {written}: the model with {len(tuned.pairs)} calibrated <pair>(s)")
    elif args.out is not None:
        lines.append(f"nothing written to {args.out}: a pair misses its target")
    document = {
        "model": str(args.model),
        "timestep_s": tuned.timestep_s,
        "integrator": tuned.integrator,
        "ok": tuned.ok,
        "written": written,
        "pairs": [
            {
                "geom1": t.pair.geom1,
                "geom2": t.pair.geom2,
                "radius_m": t.pair.radius_m,
                **design_dict(t.design, pair_element=t.element),
                "notes": [*t.pair.notes, *t.design.notes],
            }
            for t in tuned.pairs
        ],
    }
    _emit(args, lines, document)
    return 0 if tuned.ok else 1


_PAIR = re.compile(r"^\s*([^/=@\s]+)\s*/\s*([^/=@\s]+)\s*(?:=\s*([^@\s]+))?\s*(?:@\s*(\S+))?\s*$")


def number(text: str) -> float:
    """An argument that is a finite number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def restitution(text: str) -> float | RestitutionCurve:
    """An argument ``E`` or ``V:E,V:E,...`` (m/s and e) -> e or a checked curve."""
    from impactlab.contact import ContactModelError, RestitutionCurve

    if ":" not in text:
        return number(text)
    try:
        points = [item.split(":") for item in text.split(",")]
        if any(len(point) != 2 for point in points):
            raise argparse.ArgumentTypeError(
                f"must be E or SPEED:E,SPEED:E,... (m/s and e), got {text!r}"
            )
        return RestitutionCurve.of([number(v) for v, _ in points], [number(e) for _, e in points])
    except ContactModelError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def law(text: str) -> tuple[float, float]:
    """An argument ``C1,C2`` -> the two coefficients."""
    parts = text.split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"must be C1,C2 (two numbers), got {text!r}")
    return number(parts[0]), number(parts[1])


def speeds(text: str) -> tuple[float, float]:
    """An argument ``LO..HI`` or ``V`` (m/s) -> (lo, hi)."""
    lo_text, sep, hi_text = text.partition("..")
    lo = number(lo_text)
    hi = number(hi_text) if sep else lo
    if not 0.0 < lo <= hi:
        raise argparse.ArgumentTypeError(f"must be LO..HI with 0 < LO <= HI (m/s), got {text!r}")
    return lo, hi


def pair(text: str) -> PairRequest:
    """An argument ``G1/G2[=E][@LO..HI]`` -> PairRequest."""
    from impactlab.contact.tune import PairRequest

    m = _PAIR.match(text)
    if not m:
        raise argparse.ArgumentTypeError(f"must be GEOM1/GEOM2=E[@LO..HI], got {text!r}")
    g1, g2, e, at = m.groups()
    return PairRequest(g1, g2, None if e is None else number(e), None if at is None else speeds(at))
