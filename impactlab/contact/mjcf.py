"""Calibrated contacts for a user's MJCF model: what each pair of geoms is, and the model with them.

:func:`model_pairs` reads a model with MuJoCo and describes the pairs a user asks for (radius,
gravity along the contact normal, the first impact speed when it follows from the model's
initial state); :func:`with_pairs` writes the model's own text back with one ``<pair>`` per
calibrated pair, replacing a ``<pair>`` of the same geoms and leaving every other byte as it
was; :func:`check_tuned` compiles the result and checks that MuJoCo sees those parameters.
"""

from __future__ import annotations

import math
import xml.parsers.expat
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from impactlab.contact.checks import ContactModelError
from impactlab.contact.params import ContactParams


@dataclass(frozen=True)
class ModelPair:
    """One pair of geoms of a model, as the designer needs it.

    Attributes:
        geom1, geom2: geom names.
        radius_m: the smaller sphere radius in m (None when neither geom is a sphere).
        gravity_mps2: gravity along the contact normal (0 for two moving bodies).
        first_impact_mps: impact speed of a sphere falling from the model's initial state onto
            a static plane, or None when that does not follow from the model.
        condim, friction, margin, gap: the geoms' own contact settings, mixed as MuJoCo mixes
            them (kept in the calibrated ``<pair>``).
        notes: what the user should know about this pair.
    """

    geom1: str
    geom2: str
    radius_m: float | None
    gravity_mps2: float
    first_impact_mps: float | None
    condim: int
    friction: tuple[float, float, float, float, float]
    margin: float
    gap: float
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class ModelOptions:
    """The model's simulation options the calibration is for."""

    timestep_s: float
    integrator: str
    gravity: tuple[float, float, float]


def load_model(path: Path):
    """Compile an MJCF file with MuJoCo.

    Raises:
        ContactModelError: the file is missing or MuJoCo cannot compile it.
    """
    import mujoco

    if not path.is_file():
        raise ContactModelError(f"{path}: file not found")
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except Exception as exc:  # MuJoCo raises ValueError with the parser's message
        raise ContactModelError(f"{path}: invalid MJCF: {' '.join(str(exc).split())}") from None


def model_options(model) -> ModelOptions:
    """Timestep, integrator and gravity of a compiled model."""
    import mujoco

    integrator = mujoco.mjtIntegrator(int(model.opt.integrator)).name.removeprefix("mjINT_")
    names = {"EULER": "Euler", "RK4": "RK4", "IMPLICIT": "implicit", "IMPLICITFAST": "implicitfast"}
    return ModelOptions(
        timestep_s=float(model.opt.timestep),
        integrator=names.get(integrator, integrator),
        gravity=tuple(float(x) for x in model.opt.gravity),
    )


def model_pairs(model, names: Sequence[tuple[str, str]]) -> list[ModelPair]:
    """Describe the pairs (geom1, geom2) of a compiled model.

    Raises:
        ContactModelError: a geom name the model does not have, or a geom paired with itself.
    """
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    gravity = np.asarray(model.opt.gravity, float)
    free = {
        int(model.jnt_bodyid[j])
        for j in range(model.njnt)
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE
    }
    out = []
    for g1, g2 in names:
        ids = []
        for name in (g1, g2):
            gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
            if gid < 0:
                known = [model.geom(i).name for i in range(model.ngeom) if model.geom(i).name]
                raise ContactModelError(f"no geom named {name!r} (named geoms: {known})")
            ids.append(gid)
        if ids[0] == ids[1]:
            raise ContactModelError(f"a pair needs two geoms, got {g1}/{g2}")
        out.append(_describe(model, data, ids, gravity, free, (g1, g2)))
    return out


def _describe(model, data, ids, gravity, free, names) -> ModelPair:
    import mujoco

    sphere, plane = int(mujoco.mjtGeom.mjGEOM_SPHERE), int(mujoco.mjtGeom.mjGEOM_PLANE)
    types = [int(model.geom_type[i]) for i in ids]
    roots = [int(model.body_rootid[model.geom_bodyid[i]]) for i in ids]
    moving = [r in free for r in roots]
    radii = [float(model.geom_size[i][0]) for i, t in zip(ids, types, strict=True) if t == sphere]
    notes: list[str] = []
    first = None
    if all(moving):
        g_normal = 0.0  # two free bodies fall together: no relative gravity
    elif not any(moving):
        raise ContactModelError(f"{names[0]}/{names[1]}: neither geom is on a free body")
    else:
        static = ids[moving.index(False)]
        mover = ids[moving.index(True)]
        if types[moving.index(False)] == plane:
            normal = data.geom_xmat[static].reshape(3, 3)[:, 2]
            g_normal = max(-float(gravity @ normal), 0.0)
            if types[moving.index(True)] == sphere and g_normal > 0.0:
                r = float(model.geom_size[mover][0])
                height = float((data.geom_xpos[mover] - data.geom_xpos[static]) @ normal) - r
                if height > 0.0:
                    first = math.sqrt(2.0 * g_normal * height)
        else:
            g_normal = float(np.linalg.norm(gravity))
            notes.append("the static geom is not a plane: impacts are taken along gravity")
    if not radii:
        notes.append("no sphere in the pair: the contact is designed for one contact point")
    friction = np.maximum(model.geom_friction[ids[0]], model.geom_friction[ids[1]])
    return ModelPair(
        geom1=names[0],
        geom2=names[1],
        radius_m=min(radii) if radii else None,
        gravity_mps2=g_normal,
        first_impact_mps=first,
        condim=int(max(model.geom_condim[ids[0]], model.geom_condim[ids[1]])),
        friction=(
            float(friction[0]),
            float(friction[0]),
            float(friction[1]),
            float(friction[2]),
            float(friction[2]),
        ),
        margin=float(max(model.geom_margin[ids[0]], model.geom_margin[ids[1]])),
        gap=float(max(model.geom_gap[ids[0]], model.geom_gap[ids[1]])),
        notes=tuple(notes),
    )


def pair_element(pair: ModelPair, params: ContactParams) -> str:
    """The ``<pair>`` element: the calibrated solref/solimp and the geoms' own friction."""
    a = params.mjcf_attributes()
    attrs = [
        f"geom1={quoteattr(pair.geom1)}",
        f"geom2={quoteattr(pair.geom2)}",
        f'condim="{pair.condim}"',
        'friction="' + " ".join(f"{x:g}" for x in pair.friction) + '"',
    ]
    if pair.margin or pair.gap:
        attrs += [f'margin="{pair.margin!r}"', f'gap="{pair.gap!r}"']
    attrs += [f'solref="{a["solref"]}"', f'solimp="{a["solimp"]}"']
    return "<pair " + " ".join(attrs) + "/>"


@dataclass
class _Layout:
    """Where things are in the model's bytes (from expat)."""

    root_end: int | None = None
    contact: tuple[int, int, bool] | None = None  # first top-level <contact>: start, end, empty
    pairs: list[tuple[frozenset[str], int, int, dict]] | None = None  # geoms, span, attributes


def _layout(raw: bytes) -> _Layout:
    parser = xml.parsers.expat.ParserCreate()
    layout = _Layout(pairs=[])
    stack: list[tuple[str, int, dict]] = []

    def start(name, attrs):
        stack.append((name, parser.CurrentByteIndex, attrs))

    def end(name):
        _, begin, attrs = stack.pop()
        here = parser.CurrentByteIndex  # the end tag, or what follows an empty element
        head = _tag_end(raw, begin)
        empty = raw[head - 2 : head] == b"/>"
        stop = head if empty else raw.index(b">", here) + 1
        if name == "mujoco" and not stack:
            layout.root_end = here if not empty else None
        elif name == "contact" and len(stack) == 1 and layout.contact is None:
            layout.contact = (begin, here if not empty else stop, empty)
        elif name == "pair" and stack and stack[-1][0] == "contact":
            geoms = frozenset((attrs.get("geom1", ""), attrs.get("geom2", "")))
            layout.pairs.append((geoms, begin, stop, attrs))

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(raw, True)
    except xml.parsers.expat.ExpatError as exc:
        raise ContactModelError(f"the model's XML cannot be parsed: {exc}") from None
    return layout


def _tag_end(raw: bytes, begin: int) -> int:
    """End (exclusive) of the tag starting at `begin`, skipping quoted attribute values."""
    quote = None
    for i in range(begin, len(raw)):
        c = raw[i : i + 1]
        if quote:
            quote = None if c == quote else quote
        elif c in (b'"', b"'"):
            quote = c
        elif c == b">":
            return i + 1
    raise ContactModelError("the model's XML ends inside a tag")


def _indent(raw: bytes, pos: int) -> bytes:
    line_start = raw.rfind(b"\n", 0, pos) + 1
    prefix = raw[line_start:pos]
    return prefix if not prefix.strip() else b""


def with_pairs(text: str, elements: Sequence[tuple[str, str, str]]) -> str:
    """The model text with a ``<pair>`` element per (geom1, geom2, element) added.

    A ``<pair>`` of the same two geoms in the model's top-level ``<contact>`` is replaced;
    the others go into that ``<contact>`` (or a new one before ``</mujoco>``). Every other
    byte of the text is kept.

    Raises:
        ContactModelError: the text is not XML with a ``<mujoco>`` root.
    """
    raw = text.encode("utf-8")
    layout = _layout(raw)
    if layout.root_end is None:
        raise ContactModelError("the model has no <mujoco> root element with an end tag")
    edits: list[tuple[int, int, bytes]] = []
    new: list[bytes] = []
    for g1, g2, element in elements:
        match = [p for p in layout.pairs or () if p[0] == frozenset((g1, g2))]
        if match:
            _, start, stop, attrs = match[0]
            if attrs.get("geom1") == g2:  # keep the pair's order (the normal's direction)
                names = f"geom1={quoteattr(g1)} geom2={quoteattr(g2)}"
                element = element.replace(names, f"geom1={quoteattr(g2)} geom2={quoteattr(g1)}")
            if "name" in attrs:  # keep the pair's name: other elements may refer to it
                element = element.replace("<pair ", f"<pair name={quoteattr(attrs['name'])} ", 1)
            edits += [(start, stop, element.encode())]
            edits += [(start, stop, b"") for _, start, stop, _ in match[1:]]
        else:
            new.append(element.encode())
    if new:
        if layout.contact is not None:
            start, end, empty = layout.contact
            indent = _indent(raw, start)
            body = b"".join(b"\n" + indent + b"  " + e for e in new)
            if empty:
                edits.append((start, end, b"<contact>" + body + b"\n" + indent + b"</contact>"))
            else:
                edits.append(_insert_before(raw, end, new))
        else:
            end = layout.root_end
            inner = b"  "
            block = b"<contact>" + b"".join(b"\n" + inner * 2 + e for e in new)
            block += b"\n" + inner + b"</contact>\n"
            lead = b"" if _indent(raw, end) or raw[end - 1 : end] == b"\n" else b"\n"
            edits.append((end, end, lead + inner + block))
    out = raw
    for start, stop, data in sorted(edits, reverse=True):
        out = out[:start] + data + out[stop:]
    return out.decode("utf-8")


def _insert_before(raw: bytes, end: int, elements: list[bytes]) -> tuple[int, int, bytes]:
    """Insert elements before a ``</contact>`` end tag, indented like the tag's line."""
    line_start = raw.rfind(b"\n", 0, end) + 1
    indent = raw[line_start:end]
    if indent.strip():  # the end tag follows other content on its line
        return end, end, b"".join(b"\n  " + e for e in elements) + b"\n"
    inner = indent + b"  "
    return line_start, line_start, b"".join(inner + e + b"\n" for e in elements)


def check_tuned(path: Path, pairs: Sequence[tuple[ModelPair, ContactParams]]) -> None:
    """Compile a tuned model and check MuJoCo has exactly one pair per geom pair, as designed.

    Raises:
        ContactModelError: it does not compile (e.g. an include or asset path relative to
            another folder) or a pair is missing, doubled or different.
    """
    import mujoco

    model = load_model(path)
    for pair, params in pairs:
        g = {
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
            for name in (pair.geom1, pair.geom2)
        }
        found = [
            i
            for i in range(model.npair)
            if {int(model.pair_geom1[i]), int(model.pair_geom2[i])} == g
        ]
        if len(found) != 1:
            raise ContactModelError(
                f"the written model has {len(found)} <pair> elements for "
                f"{pair.geom1}/{pair.geom2} (is there one in an included file?)"
            )
        solref = model.pair_solref[found[0]]
        if not np.allclose(solref, params.solref, rtol=1e-12, atol=0.0):
            raise ContactModelError(
                f"MuJoCo reads solref {list(solref)} for {pair.geom1}/{pair.geom2}, "
                f"expected {list(params.solref)}"
            )
