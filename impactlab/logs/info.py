"""`impactlab info`: what a log holds, read from its summary and metadata (like `mcap info`)."""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path
from typing import Any

from mcap.reader import make_reader

from impactlab.errors import LogError
from impactlab.logs import format as logformat
from impactlab.logs.reader import MAGIC as MCAP0_MAGIC


def describe(path: Path) -> str:
    """A human-readable description of one log: run, parameters, outcome, channels.

    Raises:
        LogError: the file cannot be read or has no summary.
    """
    try:
        stream = open(path, "rb")  # noqa: SIM115 (closed below)
    except FileNotFoundError:
        raise LogError(str(path), "file not found") from None
    except IsADirectoryError:
        raise LogError(str(path), "is a folder, not a log") from None
    except OSError as exc:
        raise LogError(str(path), f"cannot read: {exc.strerror or exc}") from None
    with stream:
        if stream.read(len(MCAP0_MAGIC)) != MCAP0_MAGIC:
            raise LogError(str(path), "not an MCAP file (bad magic bytes)")
        try:
            stream.seek(0)
            reader = make_reader(stream)
            summary = reader.get_summary()
            metadata = {m.name: m.metadata for m in reader.iter_metadata()}
            attachments = [a.name for a in reader.iter_attachments()]
        except Exception as exc:  # the mcap reader raises many kinds on damaged bytes
            problem = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
            raise LogError(
                str(path),
                f"truncated or damaged, no readable summary ({problem}); "
                "`impactlab analyze` reads its complete part",
            ) from None
    if summary is None or summary.statistics is None:
        raise LogError(str(path), "no summary (truncated or still being written)")
    stats = summary.statistics
    run = metadata.get(logformat.RUN_METADATA, {})
    ending = {"outcome": "incomplete", "reason": "no outcome record: the run did not finish"}
    if run:
        run = defaultdict(lambda: "?", {**run, **metadata.get(logformat.OUTCOME_METADATA, ending)})
    lines = [f"file:       {path}"]
    if run:
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


def _json(text: str, default: Any) -> Any:
    """A JSON metadata value, or `default` when it does not parse to the same type (damaged)."""
    try:
        value = json.loads(text)
    except ValueError:
        return default
    return value if isinstance(value, type(default)) else default
