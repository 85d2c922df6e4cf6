"""Compare two impactlab logs channel by channel and field by field, within tolerances.

`diff_logs(a, b)` takes two decoded logs (`impactlab.logs.load.RunLog`) and returns a
`LogDiff`: pure data, rendered by `LogDiff.report()` (for people) or `LogDiff.to_dict()`
(JSON for machines). What is compared:

- channels, as load.py decodes them: `/bodies/<body>/state` and `/energy` matched on `t_ns`,
  `/contacts/<geom1>/<geom2>` on (`t_ns`, point index), `/events` on (`t_ns`, order). Per
  channel: messages present in one log and not the other (count, first and last time); per
  field of the matched messages: the first time the values differ beyond the tolerance, the
  largest difference and when. `/tf` and `/scene` are not decoded by load.py and not compared
  (they are derived from the body states and the model, which are).
- numbers differ beyond tolerance when `|a - b| > atol + rtol * max(|a|, |b|)`; NaN equals NaN,
  a NaN against a number (or an infinity against anything else) always differs. With
  `atol = rtol = 0` the comparison is exact (decoded doubles equal, so -0.0 equals 0.0).
- text fields (contact body names, event level and message) must be equal.
- metadata, key by key (records `impactlab.run` and `impactlab.outcome`), as exact strings,
  except the keys in `ignore_meta` (by default `impactlab_version`: a new release with the
  same physics gives an equal log). JSON values (spec, sweep, bodies, ...) are reported by
  the paths inside them that changed.
- attachments (`model.xml`) byte for byte; a difference names the first differing line.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from mcap.records import Attachment
from mcap.stream_reader import StreamReader

from impactlab.logs import format as logformat
from impactlab.logs.load import BODY_FIELDS, ENERGY_FIELDS, POINT_FIELDS, RunLog

DEFAULT_ATOL = 1e-9
DEFAULT_RTOL = 1e-9
DEFAULT_IGNORED_META = ("impactlab_version",)
CONTACT_TEXT_FIELDS = ("body1", "body2")
EVENT_FIELDS = ("level", "message")
_VALUE_WIDTH = 80  # longest metadata / model line quoted in a report


@dataclass(frozen=True)
class Tolerance:
    """When two numbers count as equal: `|a - b| <= atol + rtol * max(|a|, |b|)`.

    Attributes:
        atol: absolute tolerance, in the field's unit.
        rtol: relative tolerance.
        fields: per-field absolute tolerances replacing `atol`, keyed by field name (`z`,
            `normal_force`: in every channel) or `TOPIC:FIELD` (`/energy:total`: one channel).
    """

    atol: float = DEFAULT_ATOL
    rtol: float = DEFAULT_RTOL
    fields: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name, value in [("atol", self.atol), ("rtol", self.rtol), *self.fields.items()]:
            if not (value >= 0 and math.isfinite(value)):
                raise ValueError(f"tolerance {name} must be finite and >= 0, got {value}")

    def atol_for(self, channel: str, name: str) -> float:
        """The absolute tolerance of one field of one channel."""
        return self.fields.get(f"{channel}:{name}", self.fields.get(name, self.atol))


DEFAULT_TOLERANCE = Tolerance()
EXACT = Tolerance(atol=0.0, rtol=0.0)


@dataclass(frozen=True)
class Missing:
    """Messages of a channel that only one log holds."""

    count: int
    first_t_ns: int
    last_t_ns: int


@dataclass(frozen=True)
class FieldDiff:
    """One field of one channel whose matched values differ (beyond tolerance or not).

    `kind` is `number`, `text` or `count` (number of contact points or events at one time).
    `first_*` describe the first difference beyond tolerance (None when all are within it),
    `max_*` the largest difference (numbers and counts only).
    """

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
    """One channel (topic) of the two logs: message counts, missing messages, field diffs."""

    channel: str
    messages_a: int
    messages_b: int
    only_a: Missing | None
    only_b: Missing | None
    fields: tuple[FieldDiff, ...]

    @property
    def equal(self) -> bool:
        """Same messages, every field within tolerance."""
        return self.only_a is None and self.only_b is None and not self.diverged

    @property
    def diverged(self) -> tuple[FieldDiff, ...]:
        """The fields that differ beyond tolerance."""
        return tuple(f for f in self.fields if f.diverged)


@dataclass(frozen=True)
class MetaDiff:
    """One metadata key whose values differ (None: the key is missing from that log)."""

    record: str
    key: str
    a: str | None
    b: str | None
    changes: tuple[str, ...] = ()  # for JSON values: "path: A value, B value"


@dataclass(frozen=True)
class AttachmentDiff:
    """One attachment of either log: equal, missing from one, or different from a line on."""

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
        out = [f for c in self.channels for f in c.diverged]
        return sorted(out, key=lambda f: (f.first_t_ns, f.channel))

    def problems(self) -> list[str]:
        """One sentence per difference, earliest field divergence first."""
        lines = [_field_line(f) for f in self.diverged_fields]
        for c in self.channels:
            for side, missing, other in (
                ("A", c.only_a, c.messages_b),
                ("B", c.only_b, c.messages_a),
            ):
                if missing is None:
                    continue
                if other == 0:
                    lines.append(
                        f"{c.channel}: channel only in {side}: {_count(missing.count)}, "
                        f"{_span(missing)}"
                    )
                else:
                    lines.append(
                        f"{c.channel}: {_count(missing.count)} only in {side}, {_span(missing)}"
                    )
        lines += [_meta_line(m) for m in self.meta]
        lines += [_attachment_line(a) for a in self.attachments if not a.equal]
        return lines

    def report(self) -> str:
        """The human report: a headline naming both logs, then one line per difference."""
        tol = f"atol {self.tolerance.atol:g}, rtol {self.tolerance.rtol:g}"
        if self.tolerance.fields:
            tol += ", " + ", ".join(f"{k} atol {v:g}" for k, v in self.tolerance.fields.items())
        messages = sum(max(c.messages_a, c.messages_b) for c in self.channels)
        if self.equal:
            counted = f"{len(self.channels)} channels, {messages} messages"
            if self.ignored_meta:
                counted += f"; ignored metadata: {', '.join(self.ignored_meta)}"
            lines = [f"{self.a} and {self.b} are equal within {tol} ({counted})"]
        else:
            problems = self.problems()
            head = f"{self.a} (A) and {self.b} (B) differ ({tol}): {len(problems)} difference(s)"
            first = self.diverged_fields[:1]
            if first:
                f = first[0]
                head += f", first at t = {fmt_t(f.first_t_ns)} s in {f.channel} {f.field}"
            lines = [head] + [f"  {p}" for p in problems]
        within = [f for c in self.channels for f in c.fields if not f.diverged]
        if within:
            largest = max(within, key=lambda f: f.max_abs if f.max_abs is not None else 0.0)
            tail = f"  ({len(within)} field(s) differ within tolerance"
            if largest.max_abs is not None:
                tail += (
                    f", largest |d| = {largest.max_abs:.3g} in {largest.channel} {largest.field}"
                )
            lines.append(tail + ")")
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Everything as JSON-ready data (non-finite numbers as strings)."""
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
                {**asdict(c), "equal": c.equal, "fields": [_field_dict(f) for f in c.fields]}
                for c in self.channels
            ],
            "metadata": [asdict(m) for m in self.meta],
            "attachments": [asdict(a) for a in self.attachments],
            "notes": list(self.notes),
        }
        return _json_safe(data)


def diff_logs(
    a: RunLog,
    b: RunLog,
    *,
    tolerance: Tolerance = DEFAULT_TOLERANCE,
    ignore_meta: Iterable[str] = DEFAULT_IGNORED_META,
    attachments: bool = True,
) -> LogDiff:
    """Compare log A with log B.

    Args:
        a, b: the decoded logs (`load_log`).
        tolerance: when numbers are equal (`EXACT` for bitwise equal decoded values).
        ignore_meta: metadata keys not compared.
        attachments: also compare the attachments (read from the files again).
    """
    ignored = tuple(dict.fromkeys(ignore_meta))
    ca, cb = channel_tables(a), channel_tables(b)
    channels = []
    for topic in sorted(ca.keys() | cb.keys(), key=_topic_order):
        keys, names = (ca.get(topic) or cb[topic])[1:]
        fa = ca[topic][0] if topic in ca else None
        fb = cb[topic][0] if topic in cb else None
        channels.append(compare_channel(topic, fa, fb, keys, names, tolerance))
    notes = [
        f"{side} is incomplete: {p}" for side, log in (("A", a), ("B", b)) for p in log.problems
    ]
    return LogDiff(
        a=str(a.path),
        b=str(b.path),
        tolerance=tolerance,
        ignored_meta=ignored,
        channels=tuple(channels),
        meta=tuple(compare_meta(a.meta, b.meta, ignore=ignored)),
        attachments=tuple(
            compare_attachments(read_attachments(a.path), read_attachments(b.path))
            if attachments
            else ()
        ),
        notes=tuple(notes),
    )


Table = tuple[pl.DataFrame, tuple[str, ...], tuple[str, ...]]


def channel_tables(log: RunLog) -> dict[str, Table]:
    """Per topic: (frame, join keys, compared fields), for every channel with messages."""
    out: dict[str, Table] = {}
    for body, frame in log.bodies.items():
        if frame.height:
            out[logformat.BODY_STATE_TOPIC.format(body=body)] = (frame, ("t_ns",), BODY_FIELDS)
    if log.contacts.height:
        for (g1, g2), frame in log.contacts.group_by(["geom1", "geom2"], maintain_order=True):
            topic = f"{logformat.CONTACT_TOPIC_PREFIX}{g1}/{g2}"
            out[topic] = (
                frame.sort("t_ns", "point"),
                ("t_ns", "point"),
                POINT_FIELDS + CONTACT_TEXT_FIELDS,
            )
    if log.energy.height:
        out[logformat.ENERGY_TOPIC] = (log.energy, ("t_ns",), ENERGY_FIELDS)
    if log.events.height:
        events = log.events.with_columns(pl.int_range(pl.len()).over("t_ns").alias("seq"))
        out[logformat.EVENTS_TOPIC] = (events, ("t_ns", "seq"), EVENT_FIELDS)
    return out


def compare_channel(
    topic: str,
    fa: pl.DataFrame | None,
    fb: pl.DataFrame | None,
    keys: tuple[str, ...],
    names: tuple[str, ...],
    tolerance: Tolerance,
) -> ChannelDiff:
    """Compare one channel's frames (None: the channel is missing from that log)."""
    empty = pl.DataFrame(schema={"t_ns": pl.Int64})
    ta = fa.select("t_ns").unique() if fa is not None else empty
    tb = fb.select("t_ns").unique() if fb is not None else empty
    only_a = _missing(ta.join(tb, on="t_ns", how="anti"))
    only_b = _missing(tb.join(ta, on="t_ns", how="anti"))
    fields: list[FieldDiff] = []
    if fa is not None and fb is not None:
        if len(keys) > 1:  # several rows per message: compare how many
            fields += _count_diff(topic, fa, fb, keys[1])
        joined = fa.join(fb, on=list(keys), how="inner", suffix="_b").sort(list(keys))
        t_ns = joined["t_ns"].to_numpy()
        point = joined["point"].to_numpy() if "point" in keys else None
        for name in names:
            if joined.schema[name] == pl.String:
                diff = _text_diff(topic, name, joined, t_ns, point, tolerance)
            else:
                diff = _number_diff(topic, name, joined, t_ns, point, tolerance)
            if diff is not None:
                fields.append(diff)
    return ChannelDiff(
        channel=topic,
        messages_a=ta.height,
        messages_b=tb.height,
        only_a=only_a,
        only_b=only_b,
        fields=tuple(fields),
    )


def _missing(times: pl.DataFrame) -> Missing | None:
    if not times.height:
        return None
    t = times["t_ns"]
    return Missing(count=times.height, first_t_ns=int(t.min()), last_t_ns=int(t.max()))


def _count_diff(topic: str, fa: pl.DataFrame, fb: pl.DataFrame, unit: str) -> list[FieldDiff]:
    counts = (
        fa.group_by("t_ns")
        .len()
        .join(fb.group_by("t_ns").len(), on="t_ns", how="inner", suffix="_b")
        .sort("t_ns")
    )
    na, nb = counts["len"].to_numpy(), counts["len_b"].to_numpy()
    differ = np.flatnonzero(na != nb)
    if not differ.size:
        return []
    t = counts["t_ns"].to_numpy()
    d = np.abs(na - nb)
    i, j = int(differ[0]), int(np.argmax(d))
    name = "number of points" if unit == "point" else "number of events"
    return [
        FieldDiff(
            channel=topic,
            field=name,
            kind="count",
            compared=counts.height,
            differing=int(differ.size),
            beyond=int(differ.size),
            atol=0.0,
            rtol=0.0,
            first_t_ns=int(t[i]),
            first_a=int(na[i]),
            first_b=int(nb[i]),
            first_abs=float(d[i]),
            first_tol=0.0,
            max_abs=float(d[j]),
            max_t_ns=int(t[j]),
            max_a=int(na[j]),
            max_b=int(nb[j]),
        )
    ]


def _number_diff(
    topic: str,
    name: str,
    joined: pl.DataFrame,
    t_ns: np.ndarray,
    point: np.ndarray | None,
    tolerance: Tolerance,
) -> FieldDiff | None:
    va = joined[name].to_numpy().astype(np.float64)
    vb = joined[f"{name}_b"].to_numpy().astype(np.float64)
    same = (va == vb) | (np.isnan(va) & np.isnan(vb))
    if same.all():
        return None
    atol, rtol = tolerance.atol_for(topic, name), tolerance.rtol
    with np.errstate(invalid="ignore", over="ignore"):
        d = np.where(same, 0.0, np.abs(va - vb))
        d = np.where(np.isnan(d), np.inf, d)
        tol = atol + rtol * np.maximum(np.abs(va), np.abs(vb))
        nonfinite = ~np.isfinite(va) | ~np.isfinite(vb)
        beyond = ~same & ((d > tol) | nonfinite)
    j = int(np.argmax(d))
    first: dict[str, Any] = {}
    if beyond.any():
        i = int(np.argmax(beyond))
        first = {
            "first_t_ns": int(t_ns[i]),
            "first_point": None if point is None else int(point[i]),
            "first_a": float(va[i]),
            "first_b": float(vb[i]),
            "first_abs": float(d[i]),
            "first_tol": float(tol[i]),
        }
    return FieldDiff(
        channel=topic,
        field=name,
        kind="number",
        compared=len(va),
        differing=int((~same).sum()),
        beyond=int(beyond.sum()),
        atol=atol,
        rtol=rtol,
        max_abs=float(d[j]),
        max_t_ns=int(t_ns[j]),
        max_a=float(va[j]),
        max_b=float(vb[j]),
        **first,
    )


def _text_diff(
    topic: str,
    name: str,
    joined: pl.DataFrame,
    t_ns: np.ndarray,
    point: np.ndarray | None,
    tolerance: Tolerance,
) -> FieldDiff | None:
    va, vb = joined[name].to_list(), joined[f"{name}_b"].to_list()
    differ = [k for k, (x, y) in enumerate(zip(va, vb, strict=True)) if x != y]
    if not differ:
        return None
    i = differ[0]
    return FieldDiff(
        channel=topic,
        field=name,
        kind="text",
        compared=len(va),
        differing=len(differ),
        beyond=len(differ),
        atol=0.0,
        rtol=0.0,
        first_t_ns=int(t_ns[i]),
        first_point=None if point is None else int(point[i]),
        first_a=va[i],
        first_b=vb[i],
    )


def compare_meta(
    a: Mapping[str, str], b: Mapping[str, str], *, ignore: Iterable[str] = ()
) -> list[MetaDiff]:
    """Metadata keys whose values differ, in the order of the format (then unknown keys)."""
    skip = set(ignore)
    known = logformat.RUN_KEYS + logformat.OUTCOME_KEYS
    keys = [k for k in known if k in a or k in b]
    keys += sorted((a.keys() | b.keys()) - set(known))
    out = []
    for key in keys:
        if key in skip or a.get(key) == b.get(key):
            continue
        record = (
            logformat.OUTCOME_METADATA if key in logformat.OUTCOME_KEYS else logformat.RUN_METADATA
        )
        out.append(
            MetaDiff(record, key, a.get(key), b.get(key), _json_changes(a.get(key), b.get(key)))
        )
    return out


def _json_changes(a: str | None, b: str | None) -> tuple[str, ...]:
    """For two JSON containers: the paths inside them whose values differ."""
    try:
        ja, jb = json.loads(a or ""), json.loads(b or "")
    except ValueError:
        return ()
    if not isinstance(ja, dict | list) or not isinstance(jb, dict | list):
        return ()
    fa, fb = _flatten(ja), _flatten(jb)
    out = []
    for path in list(dict.fromkeys([*fa, *fb])):
        if fa.get(path, _ABSENT) != fb.get(path, _ABSENT):
            out.append(f"{path or '(value)'}: A {_json_value(fa, path)}, B {_json_value(fb, path)}")
    return tuple(out)


_ABSENT = object()


def _json_value(flat: Mapping[str, Any], path: str) -> str:
    return _short(json.dumps(flat[path])) if path in flat else "(absent)"


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


def read_attachments(path: Path) -> dict[str, bytes]:
    """Every complete attachment record of an MCAP file (a damaged tail ends the read)."""
    out: dict[str, bytes] = {}
    try:
        with open(path, "rb") as stream:
            for record in StreamReader(stream, skip_magic=False, validate_crcs=True).records:
                if isinstance(record, Attachment):
                    out[record.name] = bytes(record.data)
    except Exception:  # a damaged file: load_log has already reported it as partial
        pass
    return out


def compare_attachments(a: Mapping[str, bytes], b: Mapping[str, bytes]) -> list[AttachmentDiff]:
    """Per attachment name: equal, missing from one log, or the first differing line."""
    out = []
    for name in sorted(a.keys() | b.keys()):
        da, db = a.get(name), b.get(name)
        size_a = None if da is None else len(da)
        size_b = None if db is None else len(db)
        if da == db:
            out.append(AttachmentDiff(name, True, size_a, size_b))
            continue
        if da is None or db is None:
            out.append(AttachmentDiff(name, False, size_a, size_b))
            continue
        la = da.decode(errors="replace").splitlines()
        lb = db.decode(errors="replace").splitlines()
        line = next(
            (k for k, (x, y) in enumerate(zip(la, lb, strict=False)) if x != y),
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


def fmt_t(t_ns: int | None) -> str:
    """Integer nanoseconds as exact seconds without trailing zeros: 412300000 -> '0.4123'."""
    if t_ns is None:
        return "?"
    sign = "-" if t_ns < 0 else ""
    s, frac = divmod(abs(int(t_ns)), 1_000_000_000)
    return sign + f"{s}.{frac:09d}".rstrip("0").rstrip(".")


def _topic_order(topic: str) -> tuple[int, str]:
    prefixes = ("/bodies/", logformat.CONTACT_TOPIC_PREFIX, logformat.ENERGY_TOPIC)
    rank = next((i for i, p in enumerate(prefixes) if topic.startswith(p)), len(prefixes))
    return rank, topic


def _count(n: int) -> str:
    return f"{n} message" + ("" if n == 1 else "s")


def _span(m: Missing) -> str:
    if m.first_t_ns == m.last_t_ns:
        return f"at t = {fmt_t(m.first_t_ns)} s"
    return f"t = {fmt_t(m.first_t_ns)} .. {fmt_t(m.last_t_ns)} s"


def _short(text: str | None) -> str:
    if text is None:
        return "(absent)"
    return text if len(text) <= _VALUE_WIDTH else text[: _VALUE_WIDTH - 3] + "..."


def _field_line(f: FieldDiff) -> str:
    where = f"t = {fmt_t(f.first_t_ns)} s" + (
        f", point {f.first_point}" if f.first_point is not None else ""
    )
    if f.kind == "text":
        return (
            f"{f.channel} {f.field}: first differs at {where}: "
            f"A {_short(repr(f.first_a))}, B {_short(repr(f.first_b))}; "
            f"{f.beyond} of {f.compared} differ"
        )
    if f.kind == "count":
        return (
            f"{f.channel}: {f.field} first differs at {where}: A {f.first_a}, B {f.first_b}; "
            f"in {f.beyond} of {f.compared} messages"
        )
    return (
        f"{f.channel} {f.field}: first diverges at {where} "
        f"(A {f.first_a!r}, B {f.first_b!r}, |d| = {f.first_abs:.3g} > tol {f.first_tol:.3g}), "
        f"max |d| = {f.max_abs:.3g} at t = {fmt_t(f.max_t_ns)} s; "
        f"{f.beyond} of {f.compared} beyond tol"
    )


def _meta_line(m: MetaDiff) -> str:
    head = f"metadata {m.record} {m.key}"
    if m.a is None or m.b is None:
        side = "B" if m.a is None else "A"
        return f"{head}: only in {side} ({_short(repr(m.b if m.a is None else m.a))})"
    if m.changes:
        return f"{head}: " + "; ".join(m.changes)
    return f"{head}: A {_short(repr(m.a))}, B {_short(repr(m.b))}"


def _attachment_line(a: AttachmentDiff) -> str:
    if a.size_a is None or a.size_b is None:
        return f"attachment {a.name}: only in {'B' if a.size_a is None else 'A'}"
    return (
        f"attachment {a.name}: differs from line {a.first_line} "
        f"(A {_short(repr(a.line_a))}, B {_short(repr(a.line_b))}); "
        f"{a.size_a} vs {a.size_b} bytes"
    )


def _field_dict(f: FieldDiff) -> dict[str, Any]:
    d = asdict(f)
    d["diverged"] = f.diverged
    for key in ("first_t_ns", "max_t_ns"):
        d[key.replace("_ns", "_s")] = None if d[key] is None else d[key] / 1e9
    return d


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value
