"""A user's MJCF model as MuJoCo loads it, and what of it reproduces its run and keys its reuse."""

from __future__ import annotations

import hashlib
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import zstandard

from impactlab.mjcf.files import asset_files, included_files, read_text
from impactlab.mjcf.load import kept_warnings

BINARY_ATTACHMENT = "model.mjb.zst"
"""The compiled model (`binary`) as one zstd frame: mostly texture pixels, it shrinks 20-fold."""
_DECLARATION = re.compile(r"^(\s*<\?xml[^>]*encoding\s*=\s*)([\"'])(?!utf-?8\2)[^\"']*\2", re.I)
"""An XML declaration that names an encoding other than UTF-8."""


@dataclass(frozen=True)
class ModelFiles:
    """What a log keeps of a user's model.

    Attributes:
        xml: the model's MJCF text as the log stores it (UTF-8): its own file's text when it
            is one file, else MuJoCo's save of the whole model (numbers to six digits).
        needs_binary: the text alone does not reproduce the run exactly (includes, attached
            models, mesh, texture or height-field files): the compiled model goes along.
    """

    xml: str
    needs_binary: bool = False


def model_files(spec: mujoco.MjSpec, path: Path) -> ModelFiles:
    """The text the log keeps of a parsed model and whether it needs the compiled model.

    Raises:
        SpecError: the model's file cannot be read or decoded.
    """
    whole = not included_files(path) and not [p for p in asset_files(spec, path) if p.exists()]
    with kept_warnings():
        xml = _as_utf8(read_text(path)) if whole else spec.to_xml()
    return ModelFiles(xml, needs_binary=not whole)


def binary(model: mujoco.MjModel) -> bytes:
    """The compiled model as MuJoCo saves it (`mj_saveModel`), loadable with
    `mujoco.MjModel.from_binary_path`."""
    buffer = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


def binary_attachment(model: mujoco.MjModel) -> tuple[str, str, bytes]:
    """The log's attachment of the compiled model: `binary`, compressed (`BINARY_ATTACHMENT`)."""
    data = zstandard.ZstdCompressor(level=1).compress(binary(model))
    return BINARY_ATTACHMENT, "application/zstd", data


def model_digest(model: mujoco.MjModel, attachments: Sequence[tuple[str, str, bytes]]) -> str:
    """SHA-256 of the compiled model (`binary`; the log's copy among `attachments` if it has
    one): whatever MuJoCo read to build it (includes, attached models, meshes, textures), a
    change in any is another digest."""
    compiled = next((data for name, _, data in attachments if name == BINARY_ATTACHMENT), None)
    if compiled is not None:  # a zstd frame that says its size (`binary_attachment`)
        return hashlib.sha256(zstandard.ZstdDecompressor().decompress(compiled)).hexdigest()
    return hashlib.sha256(binary(model)).hexdigest()


def _as_utf8(text: str) -> str:
    """The text with its XML declaration saying UTF-8 (the log stores it as UTF-8)."""
    return _DECLARATION.sub(r"\1\2UTF-8\2", text.removeprefix("\ufeff"), count=1)
