"""Untrusted text made safe where it is written: a terminal, Markdown.

Every string a model, a spec or a log brings (names, labels, file names, an experiment's name
or description, a message quoting them) is shown as written, and never becomes markup or a
terminal escape: control characters (C0, DEL, C1, the Unicode line and paragraph separators
and bidirectional overrides) and the bytes of a file name that are not UTF-8 are shown as
their escapes (ESC as `\\x1b`), and Markdown's punctuation is backslash-escaped.
"""

from __future__ import annotations

import hashlib
import re
from urllib.parse import quote

_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f\u2028\u2029\u202a-\u202e\u2066-\u2069\udc80-\udcff]")
_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}

_MD_ALWAYS = re.compile(r"[\\`*\[\]<>&|~$]")
"""Characters that can open inline Markdown anywhere (code, emphasis, links and images,
raw HTML and autolinks, entities, table cells, strikethrough and math on GitHub)."""
_MD_UNDERSCORE = re.compile(r"(?<![0-9A-Za-z])_|_(?![0-9A-Za-z])")
"""An underscore that may open or close emphasis (one between two letters or digits cannot)."""
_MD_START = re.compile(r"( *)(?:([#=+\-])|(\d{1,9})([.)]))")
"""What makes a line a heading, a list item or a setext underline, at the text's start."""


def clipped(text: str, limit: int) -> str:
    """`text` cut to `limit` characters, "..." its last three when cut."""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def visible(text: str, keep: str = "") -> str:
    """`text` with each control character shown as its escape (`\\n`, `\\x1b`, `\\u202e`),
    except the characters in `keep`."""

    def shown(match: re.Match[str]) -> str:
        ch = match.group()
        if ch in keep:
            return ch
        code = ord(ch) - (0xDC00 if "\udc80" <= ch <= "\udcff" else 0)  # a byte of a file name
        return _NAMED.get(ch) or (f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}")

    return _CONTROL.sub(shown, text)


def terminal_text(text: str) -> str:
    """Text for a terminal: no escape sequence or other control character survives, but the
    newlines and tabs of a message of several lines."""
    return visible(text, keep="\n\t")


def one_line(text: str) -> str:
    """Text for one line of a terminal: every control character shown as its escape."""
    return visible(text)


def md_text(text: object, *, line_start: bool = True) -> str:
    """Untrusted text as Markdown that renders as exactly that text, on one line: control
    characters (newlines too) shown as escapes, Markdown punctuation backslash-escaped (`|`
    too, so it also fits a table cell), and, for text that starts a line (`line_start`), a
    leading `#`, `-`, `+`, `=` or `1.` escaped (inside a line or a table cell they are text)."""
    out = _MD_ALWAYS.sub(r"\\\g<0>", visible(str(text)))
    out = _MD_UNDERSCORE.sub(r"\\_", out)
    start = _MD_START.match(out) if line_start else None
    if start is not None:
        at = start.start(2) if start.group(2) else start.start(4)
        out = out[:at] + "\\" + out[at:]
    return out


def md_link(path: str) -> str:
    """A relative path as a Markdown link or image destination: percent-encoded but for
    letters, digits and `/_.-~=+,:@`, so no character of it ends the link or becomes markup."""
    return quote(path, safe="/=+,:@")


_FILE_UNSAFE = re.compile(r"[^A-Za-z0-9._=+-]")
FILE_PART_CHARS = 150
"""The longest name `file_part` keeps (a file name has at most 255 bytes)."""


def file_part(name: str) -> str:
    """A name (a run id, an experiment) as part of a file name in the output folder: kept
    when it is letters, digits and `._=+-` only (not starting with a dot) and short;
    otherwise those characters, the rest as `_`, and a hash of the name (so that two names
    never share a file, and no `/` or `..` leads out of the folder)."""
    short = 0 < len(name) <= FILE_PART_CHARS
    if short and not name.startswith(".") and not _FILE_UNSAFE.search(name):
        return name
    digest = hashlib.sha256(name.encode("utf-8", "surrogatepass")).hexdigest()[:8]
    return f"{_FILE_UNSAFE.sub('_', name)[:FILE_PART_CHARS].lstrip('.')}-{digest}"
