"""The report: blocks built from the tables, one function per handout question, written to
Markdown and HTML; the figures and their cache."""
