"""How impactlab's packages show their public API: lazy exports and callable stage packages.

A stage package (`impactlab.record`, `impactlab.analyze`, `impactlab.replay`) is also the
function of its name, so `impactlab.record(...)` records while `impactlab.record.spec`
stays a module: Python sets a package as an attribute of its parent when it is imported,
which would hide a function of the same name, so the package itself is made callable.
A type checker does not see a module's `__call__`: for it, `impactlab/__init__.py` imports
the functions under `TYPE_CHECKING`, and a package's lazy exports are imported there too
(its `__getattr__` hidden), so every public name has its type and a misspelt one is an error.
Exports are imported on first use, so importing one module of a package never imports the
heavy libraries its other modules need.
"""

from __future__ import annotations

import importlib
import inspect
import sys
import types
from collections.abc import Callable, Mapping
from typing import Any


def lazy_exports(package: str, exports: Mapping[str, str]) -> Callable[[str], Any]:
    """A module `__getattr__` that imports `name` from `exports[name]` (a module) on first use."""

    def __getattr__(name: str) -> Any:
        if name not in exports:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(exports[name]), name)
        setattr(sys.modules[package], name, value)
        return value

    return __getattr__


def callable_package(package: str, function: Callable[..., Any]) -> None:
    """Make the package `package` callable as `function` (signature and docstring shown)."""
    module = sys.modules[package]

    class CallablePackage(types.ModuleType):
        __call__ = staticmethod(function)

    CallablePackage.__name__ = CallablePackage.__qualname__ = f"{function.__name__}_package"
    module.__class__ = CallablePackage
    module.__signature__ = inspect.signature(function)  # type: ignore[attr-defined]
