"""Compare two logs' metadata and attachments: their numbers within a tolerance, the rest exactly.

A number written into a metadata value or the model (a designed damping, an inertia) may be
computed by numpy's vectorised kernels, whose last bit differs between machines; comparing
the text would make two recordings of one run differ. So numbers are compared as numbers,
with the tolerance of the channels (`|a - b| <= atol + rtol * max(|a|, |b|)`), and everything
around them exactly.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Mapping
from typing import Any

from impactlab.logs import format as logformat
from impactlab.logs.diff_result import EXACT, AttachmentDiff, MetaDiff, Tolerance, short
from impactlab.logs.reader import read_attachments

__all__ = ["compare_attachments", "compare_meta", "read_attachments"]

NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:inf|nan)\b")


def close(a: float, b: float, tolerance: Tolerance) -> bool:
    """Equal within the tolerance (NaN equals NaN; an infinity only itself)."""
    if a == b or (math.isnan(a) and math.isnan(b)):
        return True
    if not (math.isfinite(a) and math.isfinite(b)):
        return False
    return abs(a - b) <= tolerance.atol + tolerance.rtol * max(abs(a), abs(b))


def same_json(a: Any, b: Any, tolerance: Tolerance = EXACT) -> bool:
    """Equal JSON values, fractional numbers within the tolerance (whole ones exactly)."""
    if isinstance(a, float) and isinstance(b, float):
        return close(a, b, tolerance)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_json(a[k], b[k], tolerance) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(
            same_json(x, y, tolerance) for x, y in zip(a, b, strict=True)
        )
    return type(a) is type(b) and a == b


def same_text(a: str, b: str, tolerance: Tolerance = EXACT) -> bool:
    """Equal texts, the numbers in them within the tolerance and the rest exactly."""
    if a == b:
        return True
    na, nb = NUMBER.findall(a), NUMBER.findall(b)
    return (
        NUMBER.split(a) == NUMBER.split(b)
        and len(na) == len(nb)
        and all(close(float(x), float(y), tolerance) for x, y in zip(na, nb, strict=True))
    )


def compare_meta(
    a: Mapping[str, str],
    b: Mapping[str, str],
    *,
    ignore: Iterable[str] = (),
    tolerance: Tolerance = EXACT,
) -> list[MetaDiff]:
    """Metadata keys whose values differ, in the order of the format (then unknown keys).

    Values that parse as JSON (numbers included) are compared as JSON, numbers within the
    tolerance; other values as text, the numbers in them within the tolerance.
    """
    skip = set(ignore)
    known = logformat.RUN_KEYS + logformat.OUTCOME_KEYS
    keys = [k for k in known if k in a or k in b]
    keys += sorted((a.keys() | b.keys()) - set(known))
    out = []
    for key in keys:
        va, vb = a.get(key), b.get(key)
        if key in skip or va == vb:
            continue
        if va is not None and vb is not None:
            ja, jb = _parse(va), _parse(vb)
            if ja is not _ABSENT and jb is not _ABSENT:
                if same_json(ja, jb, tolerance):
                    continue
            elif same_text(va, vb, tolerance):
                continue
        record = (
            logformat.OUTCOME_METADATA if key in logformat.OUTCOME_KEYS else logformat.RUN_METADATA
        )
        out.append(MetaDiff(record, key, va, vb, _json_changes(va, vb, tolerance)))
    return out


def _parse(text: str) -> Any:
    try:
        return json.loads(text)
    except (ValueError, RecursionError):
        return _ABSENT


def _json_changes(a: str | None, b: str | None, tolerance: Tolerance) -> tuple[str, ...]:
    """For two JSON containers: the paths inside them whose values differ beyond tolerance."""
    ja, jb = _parse(a or ""), _parse(b or "")
    if not isinstance(ja, dict | list) or not isinstance(jb, dict | list):
        return ()
    try:
        fa, fb = _flatten(ja), _flatten(jb)
    except RecursionError:
        return ()
    out = []
    for path in list(dict.fromkeys([*fa, *fb])):
        va, vb = fa.get(path, _ABSENT), fb.get(path, _ABSENT)
        if va is _ABSENT or vb is _ABSENT or not same_json(va, vb, tolerance):
            out.append(f"{path or '(value)'}: A {_json_value(fa, path)}, B {_json_value(fb, path)}")
    return tuple(out)


_ABSENT = object()


def _json_value(flat: Mapping[str, Any], path: str) -> str:
    return short(json.dumps(flat[path])) if path in flat else "(absent)"


def _flatten(value: Any, prefix: str = "") -> dict[str, Any]:
    """Nested dicts and lists of containers as {dotted path: leaf}; scalar lists are leaves."""
    if isinstance(value, dict) and value:
        out: dict[str, Any] = {}
        for k, v in value.items():
            out |= _flatten(v, f"{prefix}.{k}" if prefix else str(k))
        return out
    if isinstance(value, list) and any(isinstance(v, dict | list) for v in value):
        out = {}
        for i, v in enumerate(value):
            out |= _flatten(v, f"{prefix}[{i}]")
        return out
    return {prefix: value}


def compare_attachments(
    a: Mapping[str, bytes], b: Mapping[str, bytes], *, tolerance: Tolerance = EXACT
) -> list[AttachmentDiff]:
    """Per attachment name: equal (texts: numbers within the tolerance), missing from one log,
    or the first differing line."""
    out = []
    for name in sorted(a.keys() | b.keys()):
        da, db = a.get(name), b.get(name)
        size_a = None if da is None else len(da)
        size_b = None if db is None else len(db)
        if da is None or db is None:
            out.append(AttachmentDiff(name, False, size_a, size_b))
            continue
        ta, tb = _text(da), _text(db)
        if da == db or (ta is not None and tb is not None and same_text(ta, tb, tolerance)):
            out.append(AttachmentDiff(name, True, size_a, size_b))
            continue
        if name.endswith(".stl") and _same_stl(da, db, tolerance):
            out.append(AttachmentDiff(name, True, size_a, size_b))
            continue
        la = (ta if ta is not None else da.decode(errors="replace")).splitlines()
        lb = (tb if tb is not None else db.decode(errors="replace")).splitlines()
        line = next(
            (
                k
                for k, (x, y) in enumerate(zip(la, lb, strict=False))
                if not same_text(x, y, tolerance)
            ),
            min(len(la), len(lb)),
        )
        out.append(
            AttachmentDiff(
                name,
                False,
                size_a,
                size_b,
                first_line=line + 1,
                line_a=la[line].strip() if line < len(la) else None,
                line_b=lb[line].strip() if line < len(lb) else None,
            )
        )
    return out


def _same_stl(a: bytes, b: bytes, tolerance: Tolerance) -> bool:
    """Two STL meshes with the same triangles within the tolerance, widened to float32's
    precision (2^-22 relative: two float32 roundings of values that differ in their last
    float64 bits, as across CPUs)."""
    import numpy as np

    from impactlab.logs.geoms import decode_stl

    try:
        ta, tb = decode_stl(a), decode_stl(b)
    except ValueError:
        return False
    rtol = max(tolerance.rtol, 2.0**-22)
    return ta.shape == tb.shape and bool(
        np.all(np.abs(ta - tb) <= tolerance.atol + rtol * np.maximum(np.abs(ta), np.abs(tb)))
    )


def _text(data: bytes) -> str | None:
    try:
        return data.decode()
    except UnicodeDecodeError:
        return None
