"""`impactlab info`: what a log holds, from its summary as `mcap info` does, or by reading it.

Any valid MCAP file is described, whoever wrote it. The summary section is optional in MCAP,
and so is each of its parts: when it holds Statistics and a copy or an index of every channel,
schema, metadata and attachment record (impactlab's logs, the official writers' defaults), it
alone is read;
otherwise the whole file is read (within the reader's limits, `impactlab.logs.bounded`) and
the messages counted. A file that is truncated or damaged is an error: `impactlab analyze`
reads its complete part.
"""

from __future__ import annotations

import json
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from mcap.reader import make_reader

from impactlab.errors import LogError
from impactlab.files import UnreadableInput, open_regular
from impactlab.logs import format as logformat
from impactlab.logs.metadata import check_channels, check_metadata
from impactlab.logs.reader import MAGIC as MCAP0_MAGIC
from impactlab.logs.reader import read_mcap
from impactlab.text import one_line


@dataclass
class Overview:
    """What a file holds, from its summary or from reading it.

    Attributes:
        library: the writer, as the file's header says.
        metadata: metadata records by name.
        attachments: attachment names, in file order.
        channels: (topic, message count, schema name, channel metadata), by channel id.
        messages: number of messages.
        start_ns, end_ns: first and last log_time (None without messages).
        counted: how the counts were found (empty: from the summary's Statistics).
    """

    library: str
    metadata: dict[str, dict[str, str]]
    attachments: list[str]
    channels: list[tuple[str, int, str, dict[str, str]]]
    messages: int
    start_ns: int | None
    end_ns: int | None
    counted: str = ""


def describe(path: Path) -> str:
    """A human-readable description of one MCAP file: run, parameters, outcome, channels.

    Raises:
        LogError: the file cannot be read, is not MCAP, or is truncated or damaged.
    """
    try:
        with open_regular(path) as stream:
            magic = stream.read(len(MCAP0_MAGIC))
    except FileNotFoundError:
        raise LogError(str(path), "file not found") from None
    except IsADirectoryError:
        raise LogError(str(path), "is a folder, not a log") from None
    except UnreadableInput as exc:
        raise LogError(str(path), f"{exc}: not a log") from None
    except OSError as exc:
        raise LogError(str(path), f"cannot read: {exc.strerror or exc}") from None
    if magic != MCAP0_MAGIC:
        raise LogError(str(path), "not an MCAP file (bad magic bytes)")
    overview = from_summary(path) or from_reading(path)
    return render(path, overview)


def from_summary(path: Path) -> Overview | None:
    """The overview from the summary section; None unless it holds Statistics and, for every
    channel, schema, metadata and attachment record the Statistics count, its copy or index."""
    try:
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            summary = reader.get_summary()
            stats = summary.statistics if summary is not None else None
            if (
                summary is None
                or stats is None
                or len(summary.metadata_indexes) != stats.metadata_count
                or len(summary.attachment_indexes) != stats.attachment_count
                or len(summary.channels) != stats.channel_count
                or len(summary.schemas) != stats.schema_count
            ):
                return None
            metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            library = reader.get_header().library
    except Exception:  # the mcap reader raises many kinds on damaged bytes: read it instead
        return None
    channels = []
    for cid, channel in sorted(summary.channels.items()):
        schema = summary.schemas.get(channel.schema_id)
        count = stats.channel_message_counts.get(cid, 0)
        channels.append(
            (channel.topic, count, schema.name if schema else "", dict(channel.metadata))
        )
    has_messages = stats.message_count > 0
    return Overview(
        library=library,
        metadata=metadata,
        attachments=[a.name for a in summary.attachment_indexes],
        channels=channels,
        messages=stats.message_count,
        start_ns=stats.message_start_time if has_messages else None,
        end_ns=stats.message_end_time if has_messages else None,
    )


def from_reading(path: Path) -> Overview:
    """The overview of a file without a usable summary, by reading every record.

    Raises:
        LogError: the file cannot be read, or is truncated or damaged.
    """
    try:
        content = read_mcap(path)
    except ValueError as exc:
        raise LogError(str(path), str(exc)) from None
    except OSError as exc:
        raise LogError(str(path), f"cannot read: {exc.strerror or exc}") from None
    if content.problems:
        raise LogError(
            str(path),
            f"truncated or damaged ({content.problems[0].removeprefix('damaged: ')}); "
            "`impactlab analyze` reads its complete part",
        )
    times = [t for c in content.channels.values() for t, _ in c.pieces if len(t)]
    all_times = np.concatenate(times) if times else np.empty(0, np.int64)
    return Overview(
        library=content.library,
        metadata=content.metadata,
        attachments=list(content.attachments),
        channels=[
            (c.topic, c.count, c.schema, dict(c.metadata))
            for _, c in sorted(content.channels.items())
        ],
        messages=int(all_times.size),
        start_ns=int(all_times.min()) if all_times.size else None,
        end_ns=int(all_times.max()) if all_times.size else None,
        counted=(
            "the file has a summary without Statistics: counted by reading it"
            if content.summary
            else "the file has no summary: counted by reading it"
        ),
    )


def render(path: Path, o: Overview) -> str:
    """The lines `impactlab info` prints for one file. Every line is shown as written but for
    its control characters (`impactlab.text.one_line`): what a log says is never a terminal
    escape, nor a line of its own."""
    run = o.metadata.get(logformat.RUN_METADATA, {})
    ending = {"outcome": "incomplete", "reason": "no outcome record: the run did not finish"}
    lines = [f"file:       {path}"]
    if run:
        checked = check_metadata(o.metadata)
        known = o.end_ns is not None and o.end_ns < 2**63
        last = np.array([o.end_ns] if known else [], dtype=np.int64)
        bodies = {  # the last message's time stands for every channel's (no rows are read)
            meta.get("body") or topic.removeprefix("/bodies/").split("/")[0]: last
            for topic, _, schema, meta in o.channels
            if schema == logformat.BODY_STATE_SCHEMA
        }
        check_channels(checked, bodies)
        run = defaultdict(
            lambda: "?", {**run, **o.metadata.get(logformat.OUTCOME_METADATA, ending)}
        )
        sweep, warnings = _json(run["sweep"], {}), _json(run["warnings"], [])
        lines += [
            f"experiment: {run['experiment']} ({run['source']})",
            f"run:        {run['run_id']}",
            f"sweep:      {', '.join(f'{k} = {v}' for k, v in sweep.items()) or '-'}",
            f"outcome:    {run['outcome']} ({run['reason']})",
            f"spec hash:  {run['spec_hash'][:16]}",
            f"versions:   impactlab {run['impactlab_version']}, mujoco {run['mujoco_version']}, "
            f"log format {run['log_format_version']}",
        ]
        lines += [f"warning:    {w}" for w in warnings]
        lines += [f"damaged:    {line}" for line in checked.lines()]
    else:
        lines.append("experiment: - (no impactlab.run metadata: not an impactlab log)")
        lines.append(f"written by: {o.library or '(no library named)'}")
        lines += [f"metadata:   {name}" for name in o.metadata]
    if o.start_ns is None or o.end_ns is None:
        lines.append("duration:   - (no messages)")
    else:
        lines.append(
            f"duration:   {(o.end_ns - o.start_ns) / 1e9:.6g} s ({o.start_ns / 1e9:g} .. "
            f"{o.end_ns / 1e9:g} s), {o.messages} messages"
        )
    if o.counted:
        lines.append(f"summary:    {o.counted}")
    lines += [f"attachments: {', '.join(o.attachments) or '-'}"]
    lines.append("channels:" if o.channels else "channels:   -")
    width = max((len(topic) for topic, *_ in o.channels), default=0)
    for topic, count, schema, _ in o.channels:
        lines.append(f"  {topic:<{width}}  {count:>8} msgs  {schema or '(no schema)'}")
    return "\n".join(one_line(line) for line in lines)


def _json(text: str, default: Any) -> Any:
    """A JSON metadata value, or `default` when it does not parse to the same type (damaged)."""
    try:
        value = json.loads(text)
    except (ValueError, RecursionError):
        return default
    return value if isinstance(value, type(default)) else default
