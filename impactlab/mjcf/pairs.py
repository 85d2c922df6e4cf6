"""An MJCF model's bytes with ``<pair>`` elements written in, every other byte kept."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from impactlab.errors import SpecError
from impactlab.mjcf.files import elements, encoding

_ATTR_ESCAPES = {"&": "&amp;", "<": "&lt;", ">": "&gt;", "\n": "&#10;", "\r": "&#13;", "\t": "&#9;"}


def quoteattr(value: str) -> str:
    """`xml.sax.saxutils.quoteattr`, whose module imports urllib.request, http and ssl (about
    15 ms of every record command's start-up)."""
    text = "".join(_ATTR_ESCAPES.get(ch, ch) for ch in value)
    if '"' not in text:
        return f'"{text}"'
    if "'" not in text:
        return f"'{text}'"
    return '"' + text.replace('"', "&quot;") + '"'


@dataclass
class _Layout:
    """Where things are in the model's bytes: the root's end tag (None when it has none), the
    first top-level ``<contact>`` (start, end, empty), each ``<pair>`` in a ``<contact>``."""

    root_end: int | None = None
    contact: tuple[int, int, bool] | None = None
    pairs: list[tuple[frozenset[str], int, int, dict[str, str]]] = field(default_factory=list)


def _layout(raw: bytes, source: str) -> _Layout:
    layout = _Layout()
    found = elements(raw, source)
    for e in found:
        if e.name == "mujoco" and not e.parent and not e.empty:
            layout.root_end = e.close
        elif e.name == "contact" and e.parent == "mujoco" and layout.contact is None:
            layout.contact = (e.start, e.stop if e.empty else e.close, e.empty)
        elif e.name == "pair" and e.parent == "contact":
            geoms = frozenset((e.attrs.get("geom1", ""), e.attrs.get("geom2", "")))
            layout.pairs.append((geoms, e.start, e.stop, e.attrs))
    return layout


def _indent(raw: bytes, pos: int) -> bytes:
    line_start = raw.rfind(b"\n", 0, pos) + 1
    prefix = raw[line_start:pos]
    return prefix if not prefix.strip() else b""


def with_pairs(raw: bytes, elements: Sequence[tuple[str, str, str]], source: str) -> bytes:
    """The model's bytes with a ``<pair>`` element per (geom1, geom2, element) added (each
    pair of geoms given once).

    A ``<pair>`` of the same two geoms in the model's top-level ``<contact>`` is replaced;
    the others go into that ``<contact>`` (or a new one before ``</mujoco>``). Every other
    byte is kept: the new text is written in the file's encoding and with its line ends.

    Raises:
        SpecError: the text (of the file `source`) is not XML with a ``<mujoco>`` root,
            or a name cannot be written in the file's encoding.
    """
    charset = encoding(raw, source)
    if "<".encode(charset, errors="replace") != b"<":
        raise SpecError(source, "", f"the model is {charset} text: save it as UTF-8")
    nl = b"\r\n" if b"\r\n" in raw else b"\n"
    layout = _layout(raw, source)
    if layout.root_end is None:
        raise SpecError(source, "", "the model has no <mujoco> root element with an end tag")
    edits: list[tuple[int, int, bytes]] = []
    new: list[bytes] = []
    for g1, g2, element in elements:
        match = [p for p in layout.pairs if p[0] == frozenset((g1, g2))]
        if match:
            _, start, stop, attrs = match[0]
            if attrs.get("geom1") == g2:  # keep the pair's order (the normal's direction)
                names = f"geom1={quoteattr(g1)} geom2={quoteattr(g2)}"
                element = element.replace(names, f"geom1={quoteattr(g2)} geom2={quoteattr(g1)}")
            if "name" in attrs:  # keep the pair's name: other elements may refer to it
                element = element.replace("<pair ", f"<pair name={quoteattr(attrs['name'])} ", 1)
            edits += [(start, stop, _encode(element, charset, source))]
            edits += [(start, stop, b"") for _, start, stop, _ in match[1:]]
        else:
            new.append(_encode(element, charset, source))
    if new:
        if layout.contact is not None:
            start, end, empty = layout.contact
            indent = _indent(raw, start)
            body = b"".join(nl + indent + b"  " + e for e in new)
            if empty:
                edits.append((start, end, b"<contact>" + body + nl + indent + b"</contact>"))
            else:
                edits.append(_insert_before(raw, end, new, nl))
        else:
            end = layout.root_end
            inner = b"  "
            block = b"<contact>" + b"".join(nl + inner * 2 + e for e in new)
            block += nl + inner + b"</contact>" + nl
            lead = b"" if _indent(raw, end) or raw[end - 1 : end] == b"\n" else nl
            edits.append((end, end, lead + inner + block))
    out = raw
    for start, stop, data in sorted(edits, reverse=True):
        out = out[:start] + data + out[stop:]
    return out


def _encode(element: str, charset: str, source: str) -> bytes:
    try:
        return element.encode(charset)
    except UnicodeEncodeError:
        raise SpecError(
            source, "", f"{element[:60]}...: a geom name cannot be written as {charset} text"
        ) from None


def _insert_before(
    raw: bytes, end: int, elements: list[bytes], nl: bytes
) -> tuple[int, int, bytes]:
    """Insert elements before a ``</contact>`` end tag, indented like the tag's line."""
    line_start = raw.rfind(b"\n", 0, end) + 1
    indent = raw[line_start:end]
    if indent.strip():  # the end tag follows other content on its line
        return end, end, b"".join(nl + b"  " + e for e in elements) + nl
    inner = indent + b"  "
    return line_start, line_start, b"".join(inner + e + nl for e in elements)
