"""An MJCF model's bytes with ``<pair>`` elements written in, every other byte kept."""

from __future__ import annotations

from collections.abc import Sequence

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


def _indent(raw: bytes, pos: int) -> bytes:
    line_start = raw.rfind(b"\n", 0, pos) + 1
    prefix = raw[line_start:pos]
    return prefix if not prefix.strip() else b""


def with_pairs(raw: bytes, new_pairs: Sequence[tuple[str, str, str]], source: str) -> bytes:
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
    found = elements(raw, source)
    root = next((e for e in found if e.name == "mujoco" and not e.parent and not e.empty), None)
    contact = next((e for e in found if e.name == "contact" and e.parent == "mujoco"), None)
    pairs = [e for e in found if e.name == "pair" and e.parent == "contact"]
    if root is None:
        raise SpecError(source, "", "the model has no <mujoco> root element with an end tag")
    edits: list[tuple[int, int, bytes]] = []
    new: list[bytes] = []
    for g1, g2, element in new_pairs:
        match = [
            p for p in pairs if {p.attrs.get("geom1", ""), p.attrs.get("geom2", "")} == {g1, g2}
        ]
        if match:
            start, stop, attrs = match[0].start, match[0].stop, match[0].attrs
            if attrs.get("geom1") == g2:  # keep the pair's order (the normal's direction)
                names = f"geom1={quoteattr(g1)} geom2={quoteattr(g2)}"
                element = element.replace(names, f"geom1={quoteattr(g2)} geom2={quoteattr(g1)}")
            if "name" in attrs:  # keep the pair's name: other elements may refer to it
                element = element.replace("<pair ", f"<pair name={quoteattr(attrs['name'])} ", 1)
            edits += [(start, stop, _encode(element, charset, source))]
            edits += [(p.start, p.stop, b"") for p in match[1:]]
        else:
            new.append(_encode(element, charset, source))
    if new and contact is not None and contact.empty:
        indent = _indent(raw, contact.start)
        body = b"".join(nl + indent + b"  " + e for e in new)
        edits.append(
            (contact.start, contact.stop, b"<contact>" + body + nl + indent + b"</contact>")
        )
    elif new:  # before the end tag of the <contact>, or of the root in a new <contact>
        at = root.close if contact is None else contact.close
        lead = b"" if _indent(raw, at) or raw[at - 1 : at] == b"\n" else nl  # a line of its own
        if contact is None:
            lines, indent = [b"  <contact>", *(b"    " + e for e in new), b"  </contact>"], b""
        else:  # one step deeper than the end tag's line
            lines, indent = [b"  " + e for e in new], _indent(raw, at)
        edits.append((at, at, lead + b"".join(line + nl + indent for line in lines)))
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
