"""The result of comparing two logs (`LogDiff`), and its report for people and for JSON.

Pure data: `impactlab.logs.diff.diff_logs` computes it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

from impactlab.logs import format as logformat
from impactlab.logs.diff_defaults import DEFAULT_ATOL as DEFAULT_ATOL
from impactlab.logs.diff_defaults import DEFAULT_IGNORED_META as DEFAULT_IGNORED_META
from impactlab.logs.diff_defaults import DEFAULT_RTOL as DEFAULT_RTOL

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
        return sorted(out, key=lambda f: (f.first_t_ns, topic_order(f.channel)))

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
        safe: dict[str, Any] = _json_safe(data)
        return safe


def fmt_t(t_ns: int | None) -> str:
    """Integer nanoseconds as exact seconds without trailing zeros: 412300000 -> '0.4123'."""
    if t_ns is None:
        return "?"
    sign = "-" if t_ns < 0 else ""
    s, frac = divmod(abs(int(t_ns)), 1_000_000_000)
    return sign + f"{s}.{frac:09d}".rstrip("0").rstrip(".")


def topic_order(topic: str) -> tuple[int, str, bool]:
    prefixes = ("/bodies/", logformat.CONTACT_TOPIC_PREFIX, logformat.ENERGY_TOPIC)
    rank = next((i for i, p in enumerate(prefixes) if topic.startswith(p)), len(prefixes))
    derived = topic.endswith("/clearance")  # a body's state before its clearance
    return rank, topic.removesuffix("/clearance").removesuffix("/state"), derived


def _count(n: int) -> str:
    return f"{n} message" + ("" if n == 1 else "s")


def _span(m: Missing) -> str:
    if m.first_t_ns == m.last_t_ns:
        return f"at t = {fmt_t(m.first_t_ns)} s"
    return f"t = {fmt_t(m.first_t_ns)} .. {fmt_t(m.last_t_ns)} s"


def short(text: str | None) -> str:
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
            f"A {short(repr(f.first_a))}, B {short(repr(f.first_b))}; "
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
        return f"{head}: only in {side} ({short(repr(m.b if m.a is None else m.a))})"
    if m.changes:
        return f"{head}: " + "; ".join(m.changes)
    return f"{head}: A {short(repr(m.a))}, B {short(repr(m.b))}"


def _attachment_line(a: AttachmentDiff) -> str:
    if a.size_a is None or a.size_b is None:
        return f"attachment {a.name}: only in {'B' if a.size_a is None else 'A'}"
    return (
        f"attachment {a.name}: differs from line {a.first_line} "
        f"(A {short(repr(a.line_a))}, B {short(repr(a.line_b))}); "
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
