"""Compare two logs channel by channel, field by field, within tolerances (`impactlab diff`)."""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
import polars as pl

from impactlab.logs import format as logformat
from impactlab.logs.decode import IMPACT_SCHEMA
from impactlab.logs.load import RunLog
from impactlab.logs.messages import BODY_FIELDS, ENERGY_FIELDS, POINT_FIELDS, WORK_FIELDS
from impactlab.logs.reader import read_attachments
from impactlab.tools import DEFAULT_IGNORED_META
from impactlab.tools.compare import (
    ABSENT,
    EXACT,
    Tolerance,
    differences,
    flatten,
    parse_json,
    same_json,
    same_text,
)
from impactlab.tools.report import (
    AttachmentDiff,
    ChannelDiff,
    FieldDiff,
    LogDiff,
    MetaDiff,
    Missing,
    fmt_t,
    short,
    topic_order,
)

__all__ = ["EXACT", "LogDiff", "Tolerance", "diff_logs", "fmt_t"]
Table = tuple[pl.DataFrame, tuple[str, ...], tuple[str, ...]]  # frame, join keys, fields
IMPACT_FIELDS = tuple(
    c
    for c, t in IMPACT_SCHEMA.items()
    if t in (pl.Float64, pl.Int64, pl.Boolean) and c != "release_ns"
)


def diff_logs(
    a: RunLog,
    b: RunLog,
    *,
    tolerance: Tolerance = Tolerance(),  # noqa: B008 (frozen)
    ignore_meta: Iterable[str] = DEFAULT_IGNORED_META,
) -> LogDiff:
    """Compare log A with log B (`tolerance`: `EXACT` for equal decoded values; `ignore_meta`:
    keys not compared), their attachments read from the files again."""
    ignored = tuple(dict.fromkeys(ignore_meta))
    ca, cb = channel_tables(a), channel_tables(b)
    channels = []
    for topic in sorted(ca.keys() | cb.keys(), key=topic_order):
        keys, names = (ca.get(topic) or cb[topic])[1:]
        if topic in ca and topic in cb:  # fields of one log only are missing in the other
            names = tuple(n for n in names if n in ca[topic][2] and n in cb[topic][2])
        fa, fb = (c[topic][0] if topic in c else None for c in (ca, cb))
        channels.append(compare_channel(topic, fa, fb, keys, names, tolerance))
    found = read_attachments(a.path), read_attachments(b.path)
    return LogDiff(
        a=str(a.path),
        b=str(b.path),
        tolerance=tolerance,
        ignored_meta=ignored,
        channels=tuple(channels),
        meta=tuple(compare_meta(a.meta, b.meta, ignore=ignored, tolerance=tolerance)),
        attachments=tuple(compare_attachments(*found, tolerance=tolerance)),
        notes=tuple(
            f"{side} is incomplete: {p}" for side, log in (("A", a), ("B", b)) for p in log.problems
        ),
    )


def channel_tables(log: RunLog) -> dict[str, Table]:
    """Per topic: (frame, join keys, compared fields), for every channel with messages."""
    out: dict[str, Table] = {}
    for body, frame in log.bodies.items():
        out[logformat.BODY_STATE_TOPIC.format(body=body)] = (frame, ("t_ns",), BODY_FIELDS)
    contacts = log.contacts.sort("t_ns", "geom1", "geom2", "point")
    points = pl.int_range(pl.len()).over("t_ns").alias("point")
    out[logformat.CONTACTS_TOPIC] = (
        contacts.with_columns(points),
        ("t_ns", "point"),
        (*POINT_FIELDS, "body1", "body2"),
    )
    for (body,), frame in log.clearance.group_by(["body"], maintain_order=True):
        field = pl.format("distance[{}]", pl.col("surface")).alias("field")
        wide = frame.with_columns(field).pivot("field", index="t_ns", values="clearance_m")
        names = tuple(c for c in wide.columns if c != "t_ns")
        out[logformat.CLEARANCE_TOPIC.format(body=str(body))] = (wide, ("t_ns",), names)
    out[logformat.ENERGY_TOPIC] = (log.energy, ("t_ns",), ENERGY_FIELDS)
    out[logformat.JOINT_ENERGY_TOPIC] = (log.joint_energy, ("t_ns",), ENERGY_FIELDS)
    out[logformat.WORK_TOPIC] = (log.work, ("t_ns",), WORK_FIELDS)
    seq = pl.int_range(pl.len()).over("t_ns").alias("seq")
    impacts = log.impacts.with_columns(
        pl.col("release_ns").alias("t_ns"), pl.col("open").cast(pl.Int8)
    )
    out[logformat.IMPACTS_TOPIC] = (impacts.with_columns(seq), ("t_ns", "seq"), IMPACT_FIELDS)
    out[logformat.EVENTS_TOPIC] = (
        log.events.with_columns(seq),
        ("t_ns", "seq"),
        ("level", "message"),
    )
    return {topic: table for topic, table in out.items() if table[0].height}


def compare_channel(
    topic: str,
    fa: pl.DataFrame | None,
    fb: pl.DataFrame | None,
    keys: tuple[str, ...],
    names: tuple[str, ...],
    tolerance: Tolerance,
) -> ChannelDiff:
    """Compare one channel's frames (None: the channel is missing from that log), matched
    on `keys` (the time, and a point's or an event's place at that time)."""
    empty = pl.DataFrame(schema={"t_ns": pl.Int64})
    ta, tb = (f.select("t_ns").unique() if f is not None else empty for f in (fa, fb))
    fields: list[FieldDiff] = []
    if fa is not None and fb is not None:
        if len(keys) > 1:  # several rows per message: compare how many
            name = "number of points" if keys[1] == "point" else "number of events"
            counts = [f.group_by("t_ns").len(name) for f in (fa, fb)]
            exact = {name: (0.0, 0.0)}
            fields += _fields(
                topic, differences(counts[0], counts[1], ["t_ns"], exact), exact, keys
            )
        columns = {n: (tolerance.atol_for(topic, n), tolerance.rtol) for n in names}
        fields += _fields(topic, differences(fa, fb, list(keys), columns), columns, keys)
    return ChannelDiff(
        topic, ta.height, tb.height, _missing(ta, tb), _missing(tb, ta), tuple(fields)
    )


def _missing(times: pl.DataFrame, other: pl.DataFrame) -> Missing | None:
    t = times.join(other, on="t_ns", how="anti")["t_ns"]
    return Missing(t.len(), int(t.min()), int(t.max())) if t.len() else None  # type: ignore[arg-type]


def _fields(
    topic: str,
    joined: pl.DataFrame,
    columns: Mapping[str, tuple[float, float]],
    keys: tuple[str, ...],
) -> list[FieldDiff]:
    """A `FieldDiff` for each compared column of `differences` whose values differ."""
    out = []
    t = joined["t_ns"].to_numpy()
    point = joined["point"].to_numpy() if "point" in joined.columns else None
    for name, (atol, rtol) in columns.items():
        beyond = joined[f"{name}_beyond"].to_numpy()
        text = f"{name}_d" not in joined.columns
        kind = "text" if text else "count" if name.startswith("number of") else "number"
        cast = pl.String if text else pl.Int64 if kind == "count" else pl.Float64
        a, b = (joined[c].cast(cast).to_list() for c in (name, f"{name}_b"))
        d = beyond.astype(float) if text else joined[f"{name}_d"].to_numpy()
        if not (d > 0).any():
            continue
        found: dict[str, Any] = {}
        if beyond.any():
            i = int(np.argmax(beyond))
            found = {"first_t_ns": int(t[i]), "first_a": a[i], "first_b": b[i]}
            found["first_point"] = None if point is None else int(point[i])
            if not text:
                found |= {"first_abs": float(d[i]), "first_tol": float(joined[f"{name}_tol"][i])}
        if not text:
            j = int(np.argmax(d))
            found |= {"max_abs": float(d[j]), "max_t_ns": int(t[j]), "max_a": a[j], "max_b": b[j]}
        if text or kind == "count":
            atol = rtol = 0.0
        compared, differing = len(d), int((d > 0).sum())
        out.append(
            FieldDiff(
                topic, name, kind, compared, differing, int(beyond.sum()), atol, rtol, **found
            )
        )
    return out


def compare_meta(
    a: Mapping[str, str],
    b: Mapping[str, str],
    *,
    ignore: Iterable[str] = (),
    tolerance: Tolerance = EXACT,
) -> list[MetaDiff]:
    """Metadata keys whose values differ, in the order of the format (then unknown keys):
    JSON values (numbers too) as JSON, numbers within the tolerance; other values as text,
    the numbers in them within the tolerance."""
    known = [*logformat.RUN_KEYS, *logformat.OUTCOME_KEYS]
    keys = [k for k in known if k in a or k in b] + sorted((a.keys() | b.keys()) - set(known))
    out = []
    for key in (k for k in keys if k not in set(ignore)):
        va, vb = a.get(key), b.get(key)
        ja, jb = parse_json(va), parse_json(vb)
        if va == vb or (
            va is not None
            and vb is not None
            and (
                same_json(ja, jb, tolerance)
                if ABSENT not in (ja, jb)
                else same_text(va, vb, tolerance)
            )
        ):
            continue
        record = (
            logformat.OUTCOME_METADATA if key in logformat.OUTCOME_KEYS else logformat.RUN_METADATA
        )
        out.append(MetaDiff(record, key, va, vb, _json_changes(ja, jb, tolerance)))
    return out


def _json_changes(a: Any, b: Any, tolerance: Tolerance) -> tuple[str, ...]:
    """For two JSON containers: the paths inside them whose values differ beyond tolerance."""
    if not isinstance(a, dict | list) or not isinstance(b, dict | list):
        return ()
    try:
        fa, fb = flatten(a), flatten(b)
    except RecursionError:
        return ()

    def shown(flat: dict[str, Any], path: str) -> str:
        return short(json.dumps(flat[path])) if path in flat else "(absent)"

    return tuple(
        f"{path or '(value)'}: A {shown(fa, path)}, B {shown(fb, path)}"
        for path in dict.fromkeys([*fa, *fb])
        if path not in fa or path not in fb or not same_json(fa[path], fb[path], tolerance)
    )


def compare_attachments(
    a: Mapping[str, bytes], b: Mapping[str, bytes], *, tolerance: Tolerance = EXACT
) -> list[AttachmentDiff]:
    """Per attachment: equal (text: its numbers within the tolerance; STL: its vertices within
    it, at least float32's precision), missing from one log, or its first differing line."""
    out = []
    for name in sorted(a.keys() | b.keys()):
        da, db = a.get(name), b.get(name)
        if da is None or db is None:
            sizes = [None if d is None else len(d) for d in (da, db)]
            out.append(AttachmentDiff(name, False, sizes[0], sizes[1]))
            continue
        ta, tb = da.decode(errors="replace"), db.decode(errors="replace")
        texts = "\ufffd" not in ta + tb
        equal = da == db or (texts and same_text(ta, tb, tolerance))
        if equal or (name.endswith(".stl") and _same_stl(da, db, tolerance)):
            out.append(AttachmentDiff(name, True, len(da), len(db)))
            continue
        la, lb = ta.splitlines(), tb.splitlines()
        pairs = zip(la, lb, strict=False)
        line = next(
            (k for k, (x, y) in enumerate(pairs) if not same_text(x, y, tolerance)),
            min(len(la), len(lb)),
        )
        line_a, line_b = (lines[line].strip() if line < len(lines) else None for lines in (la, lb))
        out.append(AttachmentDiff(name, False, len(da), len(db), line + 1, line_a, line_b))
    return out


def _same_stl(a: bytes, b: bytes, tolerance: Tolerance) -> bool:
    """The same triangles within the tolerance, widened to float32's precision (2^-22
    relative: two float32 roundings of values that differ in their last float64 bits)."""
    from impactlab.logs.geoms import decode_stl

    try:
        ta, tb = decode_stl(a), decode_stl(b)
    except ValueError:
        return False
    rtol = max(tolerance.rtol, 2.0**-22)
    bound = tolerance.atol + rtol * np.maximum(np.abs(ta), np.abs(tb))
    return ta.shape == tb.shape and bool(np.all(np.abs(ta - tb) <= bound))
