"""A calibrated pair's MJCF attributes quote geom names as XML's own `quoteattr` does."""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

from impactlab.mjcf.pairs import quoteattr as fast_quoteattr


def test_names_are_quoted_as_xml_quotes_attributes():
    names = ["ball", "", 'a"b', "a'b", "a\"b'c", "<&>", "&amp;", "x\ny\rz\tw", "&#10;\n"]
    for name in names:
        assert fast_quoteattr(name) == quoteattr(name), name
