"""The log is the whole contract: `analyze` and `replay` never read a run's spec.

What they need of a run besides its channels is a declared metadata key read through a typed
`RunLog` field (`impactlab.logs.metadata`, docs/log-format.md); the spec stays in the log to
reproduce the run. The check reads the source (like `test_layout.py`): any `.spec` attribute,
and any "spec" key read out of a mapping (`meta["spec"]`, `values.get("spec")`), in a module
of those packages fails here, naming the module and the line.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "impactlab"
READERS = ("analyze", "replay")
SPEC = "spec"


def spec_reads(source: str) -> list[int]:
    """The lines of `source` that read a spec: `x.spec`, `x["spec"]`, `x.get("spec")`."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        attribute = isinstance(node, ast.Attribute) and node.attr == SPEC
        key = isinstance(node, ast.Subscript) and _is_spec(node.slice)
        get = (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr in ("get", "pop", "setdefault")
            and bool(node.args)
            and _is_spec(node.args[0])
        )
        if attribute or key or get:
            lines.append(node.lineno)
    return sorted(lines)


def _is_spec(node: ast.AST) -> bool:
    return isinstance(node, ast.Constant) and node.value == SPEC


def test_the_check_sees_every_way_of_reading_a_spec():
    source = (
        "a = run.spec.get('stop')\n"
        "b = run.meta['spec']\n"
        "c = run.checked.values.get('spec', {})\n"
        "d = find_spec('x').origin\n"  # importlib's spec: not a run's
        "e = run.spec_hash\n"
    )
    assert spec_reads(source) == [1, 2, 3]


@pytest.mark.parametrize("package", READERS)
def test_analyze_and_replay_read_no_spec(package: str):
    bad = [
        f"{path.relative_to(PACKAGE.parent)}:{line}"
        for path in sorted((PACKAGE / package).rglob("*.py"))
        for line in spec_reads(path.read_text())
    ]
    assert not bad, (
        f"{package} reads a run's spec (use a declared key of impactlab.logs.metadata "
        f"through a RunLog field): {', '.join(bad)}"
    )
