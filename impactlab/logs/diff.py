"""Compare two impactlab logs channel by channel and field by field, within tolerances.

`diff_logs(a, b)` takes two decoded logs (`impactlab.logs.load.RunLog`) and returns a
`LogDiff`: pure data, rendered by `LogDiff.report()` (for people) or `LogDiff.to_dict()`
(JSON for machines). What is compared:

- channels, as load.py decodes them: `/bodies/<body>/state`, `/bodies/<body>/clearance` (one
  field per surface, `distance[<surface>]`) and `/energy` matched on `t_ns`,
  `/contacts/<geom1>/<geom2>` on (`t_ns`, point index), `/events` on (`t_ns`, order). Per
  channel: messages present in one log and not the other (count, first and last time); per
  field of the matched messages: the first time the values differ beyond the tolerance, the
  largest difference and when. `/tf` and `/scene` are not decoded by load.py and not compared
  (they are derived from the body states and the model, which are).
- numbers differ beyond tolerance when `|a - b| > atol + rtol * max(|a|, |b|)`; NaN equals NaN,
  a NaN against a number (or an infinity against anything else) always differs. With
  `atol = rtol = 0` the comparison is exact (decoded doubles equal, so -0.0 equals 0.0).
- text fields (contact body names, event level and message) must be equal.
- metadata, key by key (records `impactlab.run` and `impactlab.outcome`), except the keys in
  `ignore_meta` (by default `impactlab_version`: a new release with the same physics gives an
  equal log): the numbers in them (a timestep, the masses in `bodies`, a solref in `spec`)
  within the tolerance, the rest exactly; JSON values are reported by the paths inside them
  that changed (`impactlab.logs.diff_meta`).
- attachments (`model.xml`): as text, the numbers in it within the tolerance and the rest
  exactly (byte for byte when it is not text); a difference names the first differing line.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
import polars as pl

from impactlab.logs import format as logformat
from impactlab.logs.decode import IMPACT_SCHEMA
from impactlab.logs.diff_meta import compare_attachments, compare_meta, read_attachments
from impactlab.logs.diff_result import (
    CONTACT_TEXT_FIELDS,
    DEFAULT_IGNORED_META,
    DEFAULT_TOLERANCE,
    EVENT_FIELDS,
    EXACT,
    ChannelDiff,
    FieldDiff,
    LogDiff,
    Missing,
    Tolerance,
    topic_order,
)
from impactlab.logs.load import RunLog
from impactlab.logs.messages import BODY_FIELDS, ENERGY_FIELDS, POINT_FIELDS, WORK_FIELDS

__all__ = ["EXACT", "LogDiff", "Tolerance", "diff_logs"]


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
    for topic in sorted(ca.keys() | cb.keys(), key=topic_order):
        keys, names = (ca.get(topic) or cb[topic])[1:]
        if topic in ca and topic in cb:  # fields of one log only are missing in the other
            names = tuple(n for n in names if n in ca[topic][2] and n in cb[topic][2])
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
        meta=tuple(compare_meta(a.meta, b.meta, ignore=ignored, tolerance=tolerance)),
        attachments=tuple(
            compare_attachments(
                read_attachments(a.path), read_attachments(b.path), tolerance=tolerance
            )
            if attachments
            else ()
        ),
        notes=tuple(notes),
    )


Table = tuple[pl.DataFrame, tuple[str, ...], tuple[str, ...]]


IMPACT_FIELDS = tuple(
    c
    for c, t in IMPACT_SCHEMA.items()
    if t in (pl.Float64, pl.Int64, pl.Boolean) and c != "release_ns"
)
"""The compared numbers of a contact episode (`/impacts`, one message per episode)."""


def channel_tables(log: RunLog) -> dict[str, Table]:
    """Per topic: (frame, join keys, compared fields), for every channel with messages."""
    out: dict[str, Table] = {}
    for body, frame in log.bodies.items():
        if frame.height:
            out[logformat.BODY_STATE_TOPIC.format(body=body)] = (frame, ("t_ns",), BODY_FIELDS)
    if log.contacts.height:
        out[logformat.CONTACTS_TOPIC] = (
            log.contacts.sort("t_ns", "geom1", "geom2", "point").with_columns(
                pl.int_range(pl.len()).over("t_ns").alias("point")
            ),
            ("t_ns", "point"),
            POINT_FIELDS + CONTACT_TEXT_FIELDS,
        )
    if log.clearance.height:  # one column per surface: distance[<surface>]
        for (body,), frame in log.clearance.group_by(["body"], maintain_order=True):
            wide = frame.with_columns(
                pl.format("distance[{}]", pl.col("surface")).alias("field")
            ).pivot("field", index="t_ns", values="clearance_m")
            fields = tuple(c for c in wide.columns if c != "t_ns")
            out[logformat.CLEARANCE_TOPIC.format(body=body)] = (wide, ("t_ns",), fields)
    if log.energy.height:
        out[logformat.ENERGY_TOPIC] = (log.energy, ("t_ns",), ENERGY_FIELDS)
    if log.joint_energy.height:
        out[logformat.JOINT_ENERGY_TOPIC] = (log.joint_energy, ("t_ns",), ENERGY_FIELDS)
    if log.work.height:
        out[logformat.WORK_TOPIC] = (log.work, ("t_ns",), WORK_FIELDS)
    if log.impacts.height:  # one message per episode, at its release
        impacts = log.impacts.with_columns(
            pl.col("release_ns").alias("t_ns"),
            pl.col("open").cast(pl.Int8),
            pl.int_range(pl.len()).over("release_ns").alias("seq"),
        )
        out[logformat.IMPACTS_TOPIC] = (impacts, ("t_ns", "seq"), IMPACT_FIELDS)
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
    t = times["t_ns"].to_numpy()
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
