"""report.html reads the report's lines from its text as it needs them (`_Lines`): the same
lines `str.splitlines(keepends=True)` gives, for every kind of line end."""

from __future__ import annotations

import itertools

import pytest

from impactlab.analyze.report.html import _Lines

ENDS = ["\n", "\r", "\r\n", "\x0b", "\x0c", "\x1c", "\x1d", "\x1e", "\x85", "\u2028", "\u2029"]


@pytest.mark.parametrize(
    "text",
    ["", "a", "a\n", "\n\n", "| x |\r\n|---|\r\n| 1 |", "\r\r\n\n", "# t\n\nend"]
    + [f"row{a}{b}last" for a, b in itertools.product(ENDS, ["", *ENDS])],
)
def test_lines_are_those_of_splitlines(text):
    want = text.splitlines(keepends=True)
    lines = _Lines(text)
    assert len(lines) == len(want)
    assert list(lines) == want
    assert lines[1:3] == want[1:3]
    with pytest.raises(IndexError):
        lines[len(want)]
