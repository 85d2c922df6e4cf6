"""The impactlab version, written into every log and printed by `impactlab --version`.

The one place it is set: `pyproject.toml` reads it from here (a constant, so that no command
pays for `importlib.metadata` at start-up).
"""

from __future__ import annotations

__version__ = "0.1.0"
