"""`impactlab diff`: two logs compared field by field within tolerances, and the report."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, replace
from typing import Any

import polars as pl

from impactlab.logs import format as logformat
from impactlab.logs.decode import IMPACT_SCHEMA
from impactlab.logs.load import RunLog
from impactlab.logs.messages import BODY_FIELDS, ENERGY_FIELDS, POINT_FIELDS, WORK_FIELDS
from impactlab.logs.reader import read_attachments
from impactlab.text import clipped
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

WIDTH = 80  # longest metadata value or model line quoted in a report


@dataclass(frozen=True)
class Missing:
    """Messages of a channel that only one log holds: how many, first and last time (ns)."""

    count: int
    first_t_ns: int
    last_t_ns: int

    def span(self) -> str:
        """`at t = 1.5 s` or `t = 1.5 .. 2 s`."""
        if self.first_t_ns == self.last_t_ns:
            return f"at t = {fmt_t(self.first_t_ns)} s"
        return f"t = {fmt_t(self.first_t_ns)} .. {fmt_t(self.last_t_ns)} s"


@dataclass(frozen=True)
class FieldDiff:
    """One field of one channel whose matched values differ; `kind` is number, text or count
    (contact points or events at one time). `first_*`: the first difference beyond the
    tolerance (None: all within it); `max_*`: the largest difference (numbers, counts)."""

    channel: str
    field: str
    kind: str
    compared: int
    differing: int
    beyond: int
    atol: float
    rtol: float
    first_t_ns: int | None = None
    first_point: int | None = None
    first_a: Any = None
    first_b: Any = None
    first_abs: float | None = None
    first_tol: float | None = None
    max_abs: float | None = None
    max_t_ns: int | None = None
    max_a: Any = None
    max_b: Any = None

    @property
    def diverged(self) -> bool:
        """Some value differs beyond the tolerance."""
        return self.beyond > 0


@dataclass(frozen=True)
class ChannelDiff:
    """One topic of the two logs: message counts, messages in one only, fields that differ."""

    channel: str
    messages_a: int
    messages_b: int
    only_a: Missing | None
    only_b: Missing | None
    fields: tuple[FieldDiff, ...]

    @property
    def equal(self) -> bool:
        """Same messages, every field within tolerance."""
        return (
            self.only_a is None and self.only_b is None and not any(f.diverged for f in self.fields)
        )


@dataclass(frozen=True)
class MetaDiff:
    """A metadata key whose values differ (None: missing from that log); `changes`: for JSON
    values, "path: A value, B value" of each path inside them that differs."""

    record: str
    key: str
    a: str | None
    b: str | None
    changes: tuple[str, ...] = ()


@dataclass(frozen=True)
class AttachmentDiff:
    """An attachment of either log: equal, missing from one, or different from a line on."""

    name: str
    equal: bool
    size_a: int | None
    size_b: int | None
    first_line: int | None = None
    line_a: str | None = None
    line_b: str | None = None


@dataclass(frozen=True)
class LogDiff:
    """The comparison of log A with log B."""

    a: str
    b: str
    tolerance: Tolerance
    ignored_meta: tuple[str, ...]
    channels: tuple[ChannelDiff, ...]
    meta: tuple[MetaDiff, ...]
    attachments: tuple[AttachmentDiff, ...]
    notes: tuple[str, ...] = ()

    @property
    def equal(self) -> bool:
        """Equal within the tolerances: channels, metadata (but ignored keys), attachments."""
        return (
            all(c.equal for c in self.channels)
            and not self.meta
            and all(a.equal for a in self.attachments)
        )

    @property
    def diverged_fields(self) -> list[FieldDiff]:
        """Fields beyond tolerance, earliest divergence first."""
        out = [f for c in self.channels for f in c.fields if f.diverged]
        return sorted(out, key=lambda f: (f.first_t_ns, topic_order(f.channel)))

    def problems(self) -> list[str]:
        """One sentence per difference, earliest field divergence first."""
        lines = [_field_line(f) for f in self.diverged_fields]
        for c in self.channels:
            for side, missing, other in (
                ("A", c.only_a, c.messages_b),
                ("B", c.only_b, c.messages_a),
            ):
                if missing is not None:
                    n = f"{missing.count} message" + ("" if missing.count == 1 else "s")
                    where = f"channel only in {side}: {n}" if other == 0 else f"{n} only in {side}"
                    lines.append(f"{c.channel}: {where}, {missing.span()}")
        for m in self.meta:
            head = f"metadata {m.record} {m.key}"
            if m.a is None or m.b is None:
                lines.append(
                    f"{head}: only in {'B' if m.a is None else 'A'} ({short(repr(m.a or m.b))})"
                )
            else:
                lines.append(
                    f"{head}: "
                    + ("; ".join(m.changes) or f"A {short(repr(m.a))}, B {short(repr(m.b))}")
                )
        for a in self.attachments:
            if a.size_a is None or a.size_b is None:
                lines.append(f"attachment {a.name}: only in {'B' if a.size_a is None else 'A'}")
            elif not a.equal:
                a_b = f"A {short(repr(a.line_a))}, B {short(repr(a.line_b))}"
                lines.append(
                    f"attachment {a.name}: differs from line {a.first_line} ({a_b}); "
                    f"{a.size_a} vs {a.size_b} bytes"
                )
        return lines

    def report(self) -> str:
        """The human report: a headline naming both logs, then one line per difference."""
        tol = f"atol {self.tolerance.atol:g}, rtol {self.tolerance.rtol:g}"
        tol += "".join(f", {k} atol {v:g}" for k, v in self.tolerance.fields.items())
        if self.equal:
            messages = sum(max(c.messages_a, c.messages_b) for c in self.channels)
            counted = f"{len(self.channels)} channels, {messages} messages"
            counted += (
                f"; ignored metadata: {', '.join(self.ignored_meta)}" if self.ignored_meta else ""
            )
            lines = [f"{self.a} and {self.b} are equal within {tol} ({counted})"]
        else:
            problems = self.problems()
            head = f"{self.a} (A) and {self.b} (B) differ ({tol}): {len(problems)} difference(s)"
            for f in self.diverged_fields[:1]:
                head += f", first at t = {fmt_t(f.first_t_ns)} s in {f.channel} {f.field}"
            lines = [head] + [f"  {p}" for p in problems]
        within = [f for c in self.channels for f in c.fields if not f.diverged]
        if within:
            largest = max(within, key=lambda f: f.max_abs or 0.0)
            tail = f"  ({len(within)} field(s) differ within tolerance"
            if largest.max_abs is not None:
                tail += (
                    f", largest |d| = {largest.max_abs:.3g} in {largest.channel} {largest.field}"
                )
            lines.append(tail + ")")
        return "\n".join(lines + [f"  note: {n}" for n in self.notes])

    def to_dict(self) -> dict[str, Any]:
        """Everything as JSON-ready data (times also in s; non-finite numbers as strings)."""

        def field_dict(f: FieldDiff) -> dict[str, Any]:
            d = asdict(f) | {"diverged": f.diverged}
            return d | {
                k[:-3] + "_s": None if d[k] is None else d[k] / 1e9
                for k in ("first_t_ns", "max_t_ns")
            }

        data = {
            "a": self.a,
            "b": self.b,
            "equal": self.equal,
            "tolerance": {
                "atol": self.tolerance.atol,
                "rtol": self.tolerance.rtol,
                "fields": dict(self.tolerance.fields),
            },
            "ignored_meta": list(self.ignored_meta),
            "differences": self.problems(),
            "channels": [
                asdict(c) | {"equal": c.equal, "fields": list(map(field_dict, c.fields))}
                for c in self.channels
            ],
            "metadata": [asdict(m) for m in self.meta],
            "attachments": [asdict(a) for a in self.attachments],
            "notes": list(self.notes),
        }
        return _json_safe(data)  # type: ignore[no-any-return]


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    return [_json_safe(v) for v in value] if isinstance(value, list | tuple) else value


def fmt_t(t_ns: int | None) -> str:
    """Integer nanoseconds as exact seconds without trailing zeros: 412300000 -> '0.4123'."""
    if t_ns is None:
        return "?"
    s, frac = divmod(abs(int(t_ns)), 1_000_000_000)
    return ("-" if t_ns < 0 else "") + f"{s}.{frac:09d}".rstrip("0").rstrip(".")


def topic_order(topic: str) -> tuple[int, str, bool]:
    """Bodies (each state before its clearance), contacts, energy, then the rest."""
    prefixes = ("/bodies/", logformat.CONTACTS_TOPIC, logformat.ENERGY_TOPIC)
    rank = next((i for i, p in enumerate(prefixes) if topic.startswith(p)), len(prefixes))
    return (
        rank,
        topic.removesuffix("/clearance").removesuffix("/state"),
        topic.endswith("/clearance"),
    )


def short(text: str | None) -> str:
    """A value as a report quotes it, cut to `WIDTH` characters."""
    return "(absent)" if text is None else clipped(text, WIDTH)


def _field_line(f: FieldDiff) -> str:
    where = f"t = {fmt_t(f.first_t_ns)} s" + (
        f", point {f.first_point}" if f.first_point is not None else ""
    )
    if f.kind == "text":
        return (
            f"{f.channel} {f.field}: first differs at {where}: A {short(repr(f.first_a))}, "
            f"B {short(repr(f.first_b))}; {f.beyond} of {f.compared} differ"
        )
    if f.kind == "count":
        return (
            f"{f.channel}: {f.field} first differs at {where}: A {f.first_a}, B {f.first_b}; "
            f"in {f.beyond} of {f.compared} messages"
        )
    return (
        f"{f.channel} {f.field}: first diverges at {where} (A {f.first_a!r}, B {f.first_b!r}, "
        f"|d| = {f.first_abs:.3g} > tol {f.first_tol:.3g}), max |d| = {f.max_abs:.3g} at "
        f"t = {fmt_t(f.max_t_ns)} s; {f.beyond} of {f.compared} beyond tol"
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
            fields += _fields(topic, differences(counts[0], counts[1], ["t_ns"], exact), exact)
        columns = {n: (tolerance.atol_for(topic, n), tolerance.rtol) for n in names}
        fields += _fields(topic, differences(fa, fb, list(keys), columns), columns)
    return ChannelDiff(
        topic, ta.height, tb.height, _missing(ta, tb), _missing(tb, ta), tuple(fields)
    )


def _missing(times: pl.DataFrame, other: pl.DataFrame) -> Missing | None:
    t = times.join(other, on="t_ns", how="anti")["t_ns"]
    return Missing(t.len(), int(t.min()), int(t.max())) if t.len() else None  # type: ignore[arg-type]


def _fields(
    topic: str, joined: pl.DataFrame, columns: Mapping[str, tuple[float, float]]
) -> list[FieldDiff]:
    """A `FieldDiff` for each compared column of `differences` whose values differ: its first
    value beyond the tolerance and (numbers) its largest difference, each read from its row."""
    out = []
    for name, (atol, rtol) in columns.items():
        beyond = joined[f"{name}_beyond"]
        text = f"{name}_d" not in joined.columns
        kind = "text" if text else "count" if name.startswith("number of") else "number"
        d = beyond.cast(pl.Float64) if text else joined[f"{name}_d"]
        if not (differing := int((d > 0).sum())):
            continue
        cast = pl.String if text else pl.Int64 if kind == "count" else pl.Float64
        a, b = (joined[c].cast(cast) for c in (name, f"{name}_b"))
        found: dict[str, Any] = {}
        if beyond.any():
            i = beyond.arg_true()[0]
            point = joined["point"][i] if "point" in joined.columns else None
            found = {"first_t_ns": joined["t_ns"][i], "first_a": a[i], "first_b": b[i]}
            found |= {"first_point": point}
            if not text:
                found |= {"first_abs": d[i], "first_tol": joined[f"{name}_tol"][i]}
        if not text:
            j = d.arg_max() or 0  # d holds a value > 0: never None
            found |= {"max_abs": d[j], "max_t_ns": joined["t_ns"][j], "max_a": a[j], "max_b": b[j]}
        if text or kind == "count":
            atol = rtol = 0.0
        out.append(
            FieldDiff(topic, name, kind, len(d), differing, int(beyond.sum()), atol, rtol, **found)
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
    widened = replace(tolerance, rtol=max(tolerance.rtol, 2.0**-22))
    return ta.shape == tb.shape and widened.close(ta, tb)
