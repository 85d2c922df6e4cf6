"""Shared fixtures: record small runs from inline TOML specs once per session."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def record_spec(tmp_path_factory) -> Callable[..., list[Path]]:
    """Record an inline TOML spec (cached per session); returns the log paths in run order.

    Call as `record_spec(name, toml_text, overrides=())`.
    """
    from impactlab.record.job import plan, record

    cache: dict[tuple[str, str, tuple[str, ...]], list[Path]] = {}

    def _record(name: str, toml_text: str, overrides: Sequence[str] = ()) -> list[Path]:
        key = (name, toml_text, tuple(overrides))
        if key not in cache:
            folder = tmp_path_factory.mktemp(name)
            spec = folder / f"{name}.toml"
            spec.write_text(toml_text)
            results = record(
                plan([spec], overrides=overrides), folder / "logs", echo=lambda _: None
            )
            cache[key] = [r.path for r in results]
        return cache[key]

    return _record
