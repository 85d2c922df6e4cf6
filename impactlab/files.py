"""Output files written safely: folders checked before any work, files renamed into place.

Every file impactlab writes appears under its final name only when it is complete: it is
written under a temporary name in the same folder (unique to the process) and renamed.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
import textwrap
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from impactlab.errors import ImpactlabError


class OutputError(ImpactlabError):
    """An output folder or file cannot be created or written. Exit code 2."""

    exit_code = 2

    def __init__(self, path: Path | str, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")


def check_writable(out_dir: Path) -> None:
    """Create the output folder and prove a file can be written in it, before any work.

    Raises:
        OutputError: it cannot.
    """
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out_dir, prefix=".impactlab-write-test-"):
            pass
    except OSError as exc:
        raise OutputError(out_dir, f"cannot write there: {exc.strerror or exc}") from None


def temporary_path(path: Path) -> Path:
    """The name `path` is written under until it is complete (unique to this process)."""
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


@contextlib.contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield a temporary path to write; on success it is renamed to `path`, else removed."""
    tmp = temporary_path(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text(path: Path, text: str) -> Path:
    """Write a text file atomically. Returns `path`."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


def write_bytes(path: Path, data: bytes) -> Path:
    """Write a binary file atomically. Returns `path`."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return path


def write_json(path: Path, document: Any) -> Path:
    """Write a JSON document atomically (indented; NaN and inf as null). Returns `path`."""
    return write_text(path, json.dumps(_finite(document), indent=2, default=str) + "\n")


def write_json_stream(path: Path, document: dict[str, Any]) -> Path:
    """Write `document` as `write_json` would, where every iterator in it (a generator, not a
    list) is written as a list one item at a time: a long list is never held. Returns `path`."""
    streams: dict[str, Iterator[Any]] = {}

    def mark(value: Any) -> Any:
        if isinstance(value, dict):
            return {k: mark(v) for k, v in value.items()}
        if isinstance(value, Iterator):
            marker = f"impactlab-stream-{os.getpid()}-{len(streams)}"
            streams[json.dumps(marker)] = value
            return marker
        return value

    text = json.dumps(_finite(mark(document)), indent=2, default=str) + "\n"
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as stream:
        for marker, items in streams.items():
            head, text = text.split(marker, 1)  # the markers' first places: ours, in order
            stream.write(head + "[")
            pad = " " * (len(head.rsplit("\n", 1)[-1]) - len(head.rsplit("\n", 1)[-1].lstrip()))
            first = True
            for item in items:
                dumped = json.dumps(_finite(item), indent=2, default=str)
                stream.write(("\n" if first else ",\n") + textwrap.indent(dumped, pad + "  "))
                first = False
            stream.write("]" if first else f"\n{pad}]")
        stream.write(text)
    return path


def write_parquet(frame: Any, path: Path) -> Path:
    """Write a polars frame as Parquet (zstd) atomically. Returns `path`."""
    with atomic_path(path) as tmp:
        frame.write_parquet(tmp, compression="zstd")
    return path


def _finite(value: Any) -> Any:
    """The document with every non-finite float (NaN, inf) replaced by None."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value
