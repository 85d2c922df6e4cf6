"""The files an MJCF model is made of: its includes and attached models, assets, and its text."""

from __future__ import annotations

import codecs
import re
import xml.parsers.expat
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from impactlab.errors import SpecError
from impactlab.files import open_regular

if TYPE_CHECKING:
    import mujoco

MAX_INCLUDES = 1000  # files of one model: more is a loop or not a model
_TAG = re.compile(rb"""<(?:[^>"']|"[^"]*"|'[^']*')*>""")  # a tag, quoted values skipped
_DECLARED = re.compile(rb"^\s*<\?xml[^>]*encoding\s*=\s*[\"']([A-Za-z0-9._-]+)[\"']")


@dataclass(frozen=True)
class Element:
    """One XML element of a file: byte offsets of its start tag and of its end tag (of what
    follows it when empty), where it stops, and its parent's name ("" for the root)."""

    name: str
    parent: str
    start: int
    close: int
    stop: int
    empty: bool
    attrs: dict[str, str]


def encoding(raw: bytes, source: str = "") -> str:
    """The encoding of an XML document's bytes: its BOM, its declaration, else UTF-8.

    Raises:
        SpecError: the declaration names an encoding Python does not know.
    """
    if raw.startswith(codecs.BOM_UTF8):
        return "utf-8-sig"
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return "utf-16"
    m = _DECLARED.match(raw)
    if m is None:
        return "utf-8"
    name = m.group(1).decode("ascii")
    try:
        return codecs.lookup(name).name
    except LookupError:
        raise SpecError(source, "", f"unknown encoding {name!r} in the XML declaration") from None


def read_text(path: Path) -> str:
    """An XML file's text, decoded as its declaration says (line ends kept as they are).

    Raises:
        SpecError: the file cannot be read or is not text in its encoding.
    """
    raw = _read(path)
    name = encoding(raw, str(path))
    try:
        return raw.decode(name)
    except UnicodeDecodeError as exc:
        raise SpecError(
            str(path), "", f"not {name} text: {exc.reason} at byte {exc.start}"
        ) from None


def _read(path: Path) -> bytes:
    try:
        with open_regular(path) as stream:  # a FIFO or a device: never read it
            return stream.read()
    except OSError as exc:
        raise SpecError(str(path), "", f"cannot read: {exc.strerror or exc}") from None


def elements(raw: bytes, source: str) -> list[Element]:
    """Every element of an XML document's bytes, in the order their end tags come (expat).

    Raises:
        SpecError: the bytes are not XML.
    """
    parser = xml.parsers.expat.ParserCreate()
    stack: list[tuple[str, int, dict[str, str]]] = []
    found: list[Element] = []

    def start(name: str, attrs: dict[str, str]) -> None:
        stack.append((name, parser.CurrentByteIndex, attrs))

    def end(name: str) -> None:
        _, begin, attrs = stack.pop()
        here = parser.CurrentByteIndex  # the end tag, or what follows an empty element
        tag = _TAG.match(raw, begin)  # expat read the tag: it matches
        head = tag.end() if tag else len(raw)
        empty = raw[head - 2 : head] == b"/>"
        stop = head if empty else raw.index(b">", here) + 1
        parent = stack[-1][0] if stack else ""
        found.append(Element(name, parent, begin, here, stop, empty, attrs))

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(raw, True)
    except xml.parsers.expat.ExpatError as exc:
        raise SpecError(source, "", f"the XML cannot be parsed: {exc}") from None
    return found


def _includes(raw: bytes, path: Path) -> list[tuple[str, dict[str, str]]]:
    """The ``<include>`` and ``<model file=...>`` elements of a file: (tag, attributes)."""
    if b"<include" not in raw and b"<model" not in raw:
        return []
    try:
        found = elements(raw, str(path))
    except SpecError:
        lenient = _lenient(raw)
        if lenient is None:
            raise
        return lenient
    return [
        (e.name, e.attrs)
        for e in found
        if e.name == "include" or (e.name == "model" and "file" in e.attrs)
    ]


_COMMENT = re.compile(rb"<!--.*?-->", re.S)
_INCLUDE = re.compile(rb"<include\s+file\s*=\s*([\"'])(.*?)\1\s*/>")
_ROOT = re.compile(rb"<mujoco\b[^>]*>")


def _lenient(raw: bytes) -> list[tuple[str, dict[str, str]]] | None:
    """What MuJoCo's more lenient parser reads where expat refuses (e.g. ``--`` inside a
    comment): comments blanked, ``<include file="..."/>`` elements; None without a
    ``<mujoco>`` root."""
    text = _COMMENT.sub(lambda m: b" " * len(m.group()), raw)
    head, end = _ROOT.search(text), text.rfind(b"</mujoco>")
    if head is None or end < head.end():
        return None
    return [
        ("include", {"file": m.group(2).decode("utf-8", "replace")})
        for m in _INCLUDE.finditer(text)
    ]


def included_files(path: Path) -> list[Path]:
    """Every file the model at `path` includes or attaches (`<model file=...>`), recursively,
    in document order, each once: an include's file as MuJoCo 4 resolves it (beside the
    including file) and as MuJoCo 3 did (beside the main model), each that exists.

    Raises:
        SpecError: a file cannot be read or parsed, or includes itself.
    """
    out: list[Path] = []
    _walk(path, path, [path.resolve()], out)
    return out


def _walk(main: Path, path: Path, chain: list[Path], out: list[Path]) -> None:
    for tag, attrs in _includes(_read(path), path):
        file = attrs.get("file")
        if not file:
            raise SpecError(str(path), "", "an <include> without a file")
        if tag == "model":  # an attached model: a main model of its own
            targets = [path.parent / file]
            inner_main = targets[0]
        else:
            targets = list(dict.fromkeys([path.parent / file, main.parent / file]))
            targets = [t for t in targets if t.exists()] or targets[:1]
            inner_main = main
        for target in targets:
            if target.resolve() in chain:
                raise SpecError(str(path), "", f"includes {target}, which includes it")
            if target in out:
                continue
            out.append(target)
            if len(out) > MAX_INCLUDES:
                raise SpecError(str(main), "", f"more than {MAX_INCLUDES} included files")
            if target.exists():
                _walk(inner_main, target, [*chain, target.resolve()], out)


def asset_files(spec: mujoco.MjSpec, path: Path) -> list[Path]:
    """The mesh, texture, height-field and skin files a parsed model (`MjSpec`) reads, in
    the order MuJoCo lists them, each once (paths as MuJoCo resolves them; they may be
    missing)."""
    files = [(spec.meshdir, e.file) for e in [*spec.meshes, *spec.skins, *spec.hfields]]
    files += [(spec.texturedir, f) for t in spec.textures for f in (t.file, *t.cubefiles)]
    return list(dict.fromkeys(path.parent / folder / file for folder, file in files if file))


def check_not_input(out: Path, model: Path, spec: mujoco.MjSpec) -> None:
    """Refuse to write `out` over the model or any file it is read from (its includes and
    the assets of its parsed `spec`).

    Raises:
        SpecError: `out` is one of the model's files (same path or same inode).
    """
    if not out.exists():
        return
    for file in [model, *included_files(model), *asset_files(spec, model)]:
        try:
            same = file.exists() and out.samefile(file)
        except OSError:
            same = out.resolve() == file.resolve()
        if same:
            what = "the model" if file == model else f"a file the model reads ({file})"
            raise SpecError(
                str(model),
                "-o",
                f"{out} is {what}: give another file name (the model is never overwritten)",
            )
