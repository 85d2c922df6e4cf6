"""`impactlab info`: what a log holds, read from its summary and metadata (like `mcap info`)."""

from __future__ import annotations

import json
from pathlib import Path

from mcap.exceptions import McapError
from mcap.reader import make_reader

from impactlab import logformat
from impactlab.errors import LogError


def describe(path: Path) -> str:
    """A human-readable description of one log: run, parameters, outcome, channels.

    Raises:
        LogError: the file cannot be read or has no summary.
    """
    try:
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            summary = reader.get_summary()
            metadata = {m.name: m.metadata for m in reader.iter_metadata()}
            attachments = [a.name for a in reader.iter_attachments()]
    except FileNotFoundError:
        raise LogError(str(path), "file not found") from None
    except (McapError, OSError, ValueError, EOFError) as exc:
        raise LogError(str(path), f"not a readable MCAP file ({exc})") from None
    if summary is None or summary.statistics is None:
        raise LogError(str(path), "no summary (truncated or still being written)")
    stats = summary.statistics
    run = metadata.get(logformat.RUN_METADATA, {})
    ending = {"outcome": "incomplete", "reason": "no outcome record: the run did not finish"}
    if run:
        run = {**run, **metadata.get(logformat.OUTCOME_METADATA, ending)}
    lines = [f"file:       {path}"]
    if run:
        sweep = json.loads(run.get("sweep", "{}"))
        lines += [
            f"experiment: {run['experiment']} ({run['source']})",
            f"run:        {run['run_id']}",
            f"sweep:      {', '.join(f'{k} = {v}' for k, v in sweep.items()) or '-'}",
            f"outcome:    {run['outcome']} ({run['reason']})",
            f"spec hash:  {run['spec_hash'][:16]}",
            f"versions:   impactlab {run['impactlab_version']}, mujoco {run['mujoco_version']}, "
            f"log format {run['log_format_version']}",
        ]
        lines += [f"warning:    {w}" for w in json.loads(run.get("warnings", "[]"))]
    else:
        lines.append("experiment: - (no impactlab.run metadata: not an impactlab log)")
    duration = (stats.message_end_time - stats.message_start_time) / 1e9
    lines += [
        f"duration:   {duration:.6g} s ({stats.message_start_time / 1e9:g} .. "
        f"{stats.message_end_time / 1e9:g} s), {stats.message_count} messages",
        f"attachments: {', '.join(attachments) or '-'}",
        "channels:",
    ]
    width = max((len(c.topic) for c in summary.channels.values()), default=0)
    for cid, channel in sorted(summary.channels.items()):
        schema = summary.schemas.get(channel.schema_id)
        count = stats.channel_message_counts.get(cid, 0)
        name = schema.name if schema else "(no schema)"
        lines.append(f"  {channel.topic:<{width}}  {count:>8} msgs  {name}")
    return "\n".join(lines)
