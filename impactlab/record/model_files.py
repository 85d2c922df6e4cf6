"""A user's MJCF model as files: parsed without MuJoCo's log file, and what reproduces its run.

The log of a run must reproduce it, and a log may be reused only while every file the model is
read from is unchanged. :func:`parse_mjcf` parses the model (a NaN in it is an error, and
MuJoCo's parser warnings never reach ``MUJOCO_LOG.TXT``); :func:`model_files` gives the text
the log attaches as ``model.xml`` (the file's own text; with ``<include>`` elements, the text
with every include put in its place, every number as written), the digest of every file it is
read from (itself, its includes, its mesh, texture, height-field and skin files), and, when it
reads asset files, the compiled model (``model.mjb``, `mujoco.mj_saveModel`: meshes and
textures inside) so the log alone reproduces the run.
"""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from impactlab.contact.checks import ContactModelError
from impactlab.contact.mjcf import asset_files
from impactlab.contact.mjcf_files import encoding, included_files, inlined_text, read_text
from impactlab.contact.mujoco_log import nan_warning, parse_warnings
from impactlab.errors import SpecError

BINARY_ATTACHMENT = "model.mjb"
_DECLARATION = re.compile(r"^(\ufeff?\s*<\?xml[^>]*encoding\s*=\s*)([\"'])[^\"']*\2")


@dataclass(frozen=True)
class ModelFiles:
    """What a log keeps of a user's model, and what its reuse is keyed on.

    Attributes:
        xml: the model's MJCF text (includes inlined), UTF-8 as the log stores it.
        inputs: (path relative to the model's folder, SHA-256) of every other file it reads.
        needs_binary: the model reads asset files: attach the compiled model too.
    """

    xml: str
    inputs: tuple[tuple[str, str], ...] = field(default=())
    needs_binary: bool = False


def parse_mjcf(path: Path) -> mujoco.MjSpec:
    """Parse an MJCF file with MuJoCo, its warnings kept from the working folder.

    Raises:
        SpecError: MuJoCo cannot parse it, or it holds a NaN.
    """
    try:
        spec, fresh = parse_warnings(lambda: mujoco.MjSpec.from_file(str(path)))
    except Exception as exc:  # MuJoCo raises ValueError with the parser's message
        raise SpecError(str(path), "", f"invalid MJCF: {' '.join(str(exc).split())}") from None
    nan = nan_warning(fresh)
    if nan is not None:
        raise SpecError(str(path), "", f"invalid MJCF: a number is NaN ({nan})")
    return spec


def model_files(spec: mujoco.MjSpec, path: Path) -> ModelFiles:
    """The text, digests and needs of a parsed model (see the module's docstring).

    Raises:
        SpecError: a file of the model cannot be read or decoded.
    """
    try:
        top = read_text(path)
        includes = included_files(path)
        xml = _as_utf8(inlined_text(path) if includes else top, path)
        assets = [p for p in asset_files(spec, path) if p.is_file()]
        inputs = tuple((_relative(p, path), _sha256(p.read_bytes())) for p in includes + assets)
    except ContactModelError as exc:
        raise SpecError(str(path), "", str(exc)) from None
    except OSError as exc:
        raise SpecError(str(path), "", f"cannot read a file of the model: {exc}") from None
    return ModelFiles(xml, inputs, needs_binary=bool(assets))


def binary(model: mujoco.MjModel) -> bytes:
    """The compiled model as MuJoCo saves it (`mj_saveModel`), loadable with
    `mujoco.MjModel.from_binary_path`."""
    buffer = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


def _as_utf8(text: str, path: Path) -> str:
    """The text with its XML declaration saying UTF-8 (the log stores it as UTF-8)."""
    try:
        charset = encoding(path.read_bytes()[:200])
    except ContactModelError:
        charset = "utf-8"
    if charset in ("utf-8", "utf-8-sig"):
        return text.removeprefix("\ufeff")
    return _DECLARATION.sub(r"\1\2UTF-8\2", text.removeprefix("\ufeff"), count=1)


def _relative(file: Path, model: Path) -> str:
    return os.path.relpath(file, model.parent).replace(os.sep, "/")


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()
