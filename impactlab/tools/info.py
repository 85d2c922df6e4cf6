"""`impactlab info`: what a log holds, from its summary as `mcap info` does, or by reading it."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sized
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from mcap.reader import make_reader

from impactlab.errors import LogError
from impactlab.logs import format as logformat
from impactlab.logs.checks import check_channels, check_metadata
from impactlab.logs.inputs import input_problem, log_errors
from impactlab.logs.reader import add_metadata, read_mcap
from impactlab.text import one_line


@dataclass
class Overview:
    """What a file holds: its writer, metadata records, attachment names, channels (topic,
    messages, schema, channel metadata), messages, first and last log_time (None without
    messages), and how the counts were found ("": from the summary's Statistics)."""

    library: str
    metadata: dict[str, dict[str, str]]
    conflicts: dict[str, dict[str, str]]  # keys two records of one name give differently
    attachments: list[str]
    channels: list[tuple[str, int, str, dict[str, str]]]
    messages: int
    start_ns: int | None
    end_ns: int | None
    counted: str = ""


def describe(path: Path) -> str:
    """A description of one MCAP file, whoever wrote it: run, parameters, outcome, channels.

    Raises:
        LogError: the file cannot be read, is not MCAP, or is truncated or damaged.
    """
    if (problem := input_problem(Path(path))) is not None:
        raise LogError(*problem)
    with log_errors(path):
        return render(path, from_summary(path) or from_reading(path))


def from_summary(path: Path) -> Overview | None:
    """The overview from the summary section; None unless it holds Statistics and, for every
    channel, schema, metadata and attachment record they count, its copy or index."""
    try:
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            summary = reader.get_summary()
            stats = summary.statistics if summary is not None else None
            if summary is None or stats is None:
                return None
            held: tuple[Sized, ...] = (summary.metadata_indexes, summary.attachment_indexes)
            held += (summary.channels, summary.schemas)
            counted = (stats.metadata_count, stats.attachment_count, stats.channel_count)
            if tuple(map(len, held)) != (*counted, stats.schema_count):
                return None
            metadata: dict[str, dict[str, str]] = {}
            conflicts: dict[str, dict[str, str]] = {}
            for m in reader.iter_metadata():
                add_metadata(metadata, conflicts, m.name, dict(m.metadata))
            library = reader.get_header().library
    except Exception:  # the mcap reader raises many kinds on damaged bytes: read it instead
        return None
    channels = [
        (
            c.topic,
            stats.channel_message_counts.get(cid, 0),
            getattr(summary.schemas.get(c.schema_id), "name", ""),
            dict(c.metadata),
        )
        for cid, c in sorted(summary.channels.items())
    ]
    some = stats.message_count > 0
    return Overview(
        library,
        metadata,
        conflicts,
        [a.name for a in summary.attachment_indexes],
        channels,
        stats.message_count,
        stats.message_start_time if some else None,
        stats.message_end_time if some else None,
    )


def from_reading(path: Path) -> Overview:
    """The overview of a file without a usable summary, by reading every record.

    Raises:
        LogError: the file is truncated or damaged.
    """
    content = read_mcap(path)
    if content.problems:
        raise LogError(
            str(path),
            f"truncated or damaged ({content.problems[0].removeprefix('damaged: ')}); "
            "`impactlab analyze` reads its complete part",
        )
    times = [int(f(t)) for c in content.channels.values() for t, _ in c.pieces for f in (min, max)]
    channels = [
        (c.topic, c.count, c.schema, dict(c.metadata)) for _, c in sorted(content.channels.items())
    ]
    how = "a summary without Statistics" if content.summary else "no summary"
    return Overview(
        content.library,
        content.metadata,
        content.conflicts,
        list(content.attachments),
        channels,
        sum(c[1] for c in channels),
        min(times, default=None),
        max(times, default=None),
        f"the file has {how}: counted by reading it",
    )


def render(path: Path, o: Overview) -> str:
    """The lines `impactlab info` prints for one file, each as written but for its control
    characters (`text.one_line`): what a log says is never a terminal escape, nor a line."""
    run = o.metadata.get(logformat.RUN_METADATA, {})
    lines = [f"file:       {path}"]
    if run:
        checked = check_metadata(o.metadata, o.conflicts)
        last = [o.end_ns] if o.end_ns is not None and o.end_ns < 2**63 else []
        bodies = {  # the last message's time stands for every channel's (no rows are read)
            meta.get("body") or topic.removeprefix("/bodies/").split("/")[0]: np.array(
                last, np.int64
            )
            for topic, _, schema, meta in o.channels
            if schema == logformat.BODY_STATE_SCHEMA
        }
        check_channels(checked, bodies)
        ending = {"outcome": "incomplete", "reason": "no outcome record: the run did not finish"}
        run = defaultdict(
            lambda: "?", {**run, **o.metadata.get(logformat.OUTCOME_METADATA, ending)}
        )
        sweep, warnings = checked.values.get("sweep", {}), checked.values.get("warnings", ())
        lines += [
            f"experiment: {run['experiment']} ({run['source']})",
            f"run:        {run['run_id']}",
            f"sweep:      {', '.join(f'{k} = {v}' for k, v in sweep.items()) or '-'}",
            f"outcome:    {run['outcome']} ({run['reason']})",
            f"spec hash:  {run['spec_hash'][:16]}",
            f"versions:   impactlab {run['impactlab_version']}, mujoco {run['mujoco_version']}, "
            f"log format {run['log_format_version']}",
            *(f"warning:    {w}" for w in warnings),
            *(f"damaged:    {line}" for line in checked.lines()),
        ]
    else:
        lines.append("experiment: - (no impactlab.run metadata: not an impactlab log)")
        lines.append(f"written by: {o.library or '(no library named)'}")
        lines += [f"metadata:   {name}" for name in o.metadata]
    if o.start_ns is None or o.end_ns is None:
        lines.append("duration:   - (no messages)")
    else:
        seconds = (
            f"{(o.end_ns - o.start_ns) / 1e9:.6g} s ({o.start_ns / 1e9:g} .. {o.end_ns / 1e9:g} s)"
        )
        lines.append(f"duration:   {seconds}, {o.messages} messages")
    lines += [f"summary:    {o.counted}"] if o.counted else []
    lines += [
        f"attachments: {', '.join(o.attachments) or '-'}",
        "channels:" if o.channels else "channels:   -",
    ]
    width = max((len(topic) for topic, *_ in o.channels), default=0)
    lines += [f"  {t:<{width}}  {n:>8} msgs  {s or '(no schema)'}" for t, n, s, _ in o.channels]
    return "\n".join(one_line(line) for line in lines)
