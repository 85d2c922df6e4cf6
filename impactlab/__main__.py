"""`python -m impactlab` runs the command line."""

import gc

gc.disable()  # until the command has started: see impactlab.cli

from impactlab.cli import command  # noqa: E402

raise SystemExit(command())
