"""`python -m impactlab` runs the command line."""

from impactlab.cli import command

raise SystemExit(command())
