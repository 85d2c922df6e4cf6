"""The result of comparing two logs (`LogDiff`), and its report for people and for JSON."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

from impactlab.logs import format as logformat
from impactlab.tools.compare import Tolerance

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
    if text is None:
        return "(absent)"
    return text if len(text) <= WIDTH else text[: WIDTH - 3] + "..."


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
