"""Where the tests find the repository's files, from any folder of tests/ (on the path through
`pythonpath` in pyproject.toml, like conftest.py's other helpers)."""

from __future__ import annotations

from pathlib import Path

TESTS = Path(__file__).resolve().parent  # tests/, with golden/ and the shared helpers
ROOT = TESTS.parent  # the checkout (or the unpacked sdist)
EXPERIMENTS = ROOT / "experiments"
GOLDEN = TESTS / "golden"
