"""Shared fixtures: record small runs once per session, from specs built by `specs.py` or
inline MJCF models."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import pytest


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Tests marked `extras` need an extra beyond `test` (ray, notebook, models, schemas):
    deselected unless the -m expression names the marker (`pytest -m extras`, .ci/run), so
    the README's `pytest -m "slow or not slow"` runs on the lean test install."""
    if "extras" in (config.option.markexpr or ""):
        return
    needing = [item for item in items if item.get_closest_marker("extras") is not None]
    if needing:
        config.hook.pytest_deselected(items=needing)
        items[:] = [item for item in items if item.get_closest_marker("extras") is None]


@pytest.fixture(scope="session")
def record_spec(tmp_path_factory) -> Callable[..., list[Path]]:
    """Record a spec (cached per session); returns the log paths in run order.

    Call as `record_spec(name, spec, overrides=())`, `spec` a dict of `specs.py` or TOML text.
    """
    from specs import toml

    from impactlab.record import plan, record_runs

    cache: dict[tuple[str, str, tuple[str, ...]], list[Path]] = {}

    def _record(
        name: str, spec: str | Mapping[str, Any], overrides: Sequence[str] = ()
    ) -> list[Path]:
        toml_text = spec if isinstance(spec, str) else toml(spec)
        key = (name, toml_text, tuple(overrides))
        if key not in cache:
            folder = tmp_path_factory.mktemp(name)
            path = folder / f"{name}.toml"
            path.write_text(toml_text)
            results = record_runs(plan([path], overrides=overrides), folder / "logs")
            cache[key] = [r.path for r in results]
        return cache[key]

    return _record


@pytest.fixture(scope="session")
def record_model(tmp_path_factory) -> Callable[..., Path]:
    """Record an inline MJCF model (cached per session); returns the log's path.

    Call as `record_model(name, xml_text, overrides=())`; overrides are run options such as
    `stop.max_time=1` (a time limit is required) or `logging.every=7`.
    """
    from impactlab.record import plan, record_runs

    cache: dict[tuple[str, str, tuple[str, ...]], Path] = {}

    def _record(name: str, xml_text: str, overrides: Sequence[str] = ()) -> Path:
        key = (name, xml_text, tuple(overrides))
        if key not in cache:
            folder = tmp_path_factory.mktemp(name)
            model = folder / f"{name}.xml"
            model.write_text(xml_text)
            (result,) = record_runs(plan([model], overrides=overrides), folder / "logs")
            cache[key] = result.path
        return cache[key]

    return _record


@pytest.fixture(scope="session")
def collect_lines():
    """`collect_lines(lines, level=None)`: a progress callback that keeps the lines it is sent
    (only those of `level`, "info", "warning" or "error", when given)."""

    def make(lines: list[str], level: str | None = None):
        def progress(event) -> None:
            if event.line is not None and level in (None, event.level):
                lines.append(event.line)

        return progress

    return make


@pytest.fixture
def count_calls(monkeypatch):
    """`count_calls((module, name), ...)`: wrap each function so that its calls are counted in
    the returned dict (by name); a test asserts work done as counts, never as seconds."""

    def wrap(*targets: tuple[object, str]) -> dict[str, int]:
        calls: dict[str, int] = {}
        for module, name in targets:
            original = getattr(module, name)

            def counted(*args, _name=name, _original=original, **kwargs):
                calls[_name] = calls.get(_name, 0) + 1
                return _original(*args, **kwargs)

            monkeypatch.setattr(module, name, counted)
        return calls

    return wrap
