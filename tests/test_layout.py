"""The house: no import circle, each package imports only what its docstring allows, small modules.

Imports are read from the source (every `import` statement, also those inside functions),
so a circle or a forbidden dependency fails here before anyone runs the code path.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "impactlab"
GENERATED = {"impactlab.proto.impactlab_pb2"}

STAGES = ("record", "analyze", "replay", "calibrate")
# package -> the impactlab packages and third-party roots it must not import
FORBIDDEN = {
    "impactlab.logs": {
        "impactlab": {*STAGES, "contact", "executors", "cli", "lab", "golden", "tools"},
        "third": {"mujoco", "matplotlib", "rerun"},
    },
    "impactlab.tools": {
        "impactlab": {*STAGES, "contact", "executors", "cli", "lab", "golden", "testing"},
        "third": {"mujoco", "matplotlib", "rerun"},
    },
    "impactlab.contact": {
        "impactlab": {*STAGES, "logs", "executors", "cli", "lab"},
        "third": {"polars", "matplotlib", "rerun"},
    },
    "impactlab.mjcf": {
        "impactlab": {*STAGES, "logs", "contact", "executors", "cli", "lab"},
        "third": {"numpy", "polars", "matplotlib", "rerun"},
    },
    "impactlab.executors": {
        "impactlab": {*STAGES, "logs", "contact", "cli", "lab"},
        "third": {"mujoco", "polars", "matplotlib", "rerun"},
    },
    "impactlab.record": {
        "impactlab": {"analyze", "replay", "calibrate", "cli", "lab"},
        "third": {"polars", "matplotlib", "rerun"},
    },
    "impactlab.analyze": {
        "impactlab": {"record", "replay", "calibrate", "contact", "cli", "lab"},
        "third": {"mujoco", "rerun"},
    },
    "impactlab.replay": {
        "impactlab": {"record", "analyze", "calibrate", "contact", "cli", "lab"},
        "third": {"mujoco", "matplotlib"},
    },
    "impactlab.calibrate": {"impactlab": {"replay", "cli", "lab"}, "third": {"rerun"}},
    "impactlab.testing": {
        "impactlab": {"replay", "calibrate", "contact", "cli", "lab", "golden"},
        "third": {"mujoco", "matplotlib", "rerun"},
    },
}
BASE = (
    "errors",
    "files",
    "progress",
    "packages",
    "physics",
    "plotting",
    "show",
    "text",
    "version",
)  # below every stage
FACES = {f"impactlab.{stage}" for stage in STAGES}  # what other stages may use of a stage


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _imports(name: str, path: Path) -> set[str]:
    """Every module named by an import statement of the file (absolute names)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*up, base] if base else up)
            names = {f"{base}.{a.name}" for a in node.names}
            found |= names
            if not names <= MODULE_NAMES:  # `from P import f` (not only submodules) uses P
                found.add(base)
    return found


MODULES = _modules()
MODULE_NAMES = set(MODULES)
GRAPH = {
    name: {m for m in _imports(name, path) if m in MODULES and m != name}
    for name, path in MODULES.items()
    if name not in GENERATED
}


def _owner(module: str) -> str:
    """The module's package below impactlab (or the module itself for top-level modules)."""
    parts = module.split(".")
    return ".".join(parts[:2])


def test_no_import_circle():
    """Depth-first search for a back edge; the message names the circle."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(GRAPH.get(node, ())):
            if state.get(nxt) == 1:
                circle = [*stack[stack.index(nxt) :], nxt]
                pytest.fail("import circle: " + " -> ".join(circle))
            if nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = 2

    for node in sorted(GRAPH):
        if node not in state:
            visit(node)


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_package_imports_only_what_it_may(package: str):
    rules = FORBIDDEN[package]
    bad = []
    for name, path in MODULES.items():
        if name != package and not name.startswith(package + "."):
            continue
        for imported in _imports(name, path):
            root = imported.split(".")[0]
            if root == "impactlab":
                sub = imported.split(".")[1] if "." in imported else ""
                if sub in rules["impactlab"]:
                    bad.append(f"{name} imports {imported}")
            elif root in rules["third"]:
                bad.append(f"{name} imports {imported}")
    assert not bad, "\n".join(bad)


def test_calibrate_and_lab_use_the_other_stages_public_faces_only():
    """`from impactlab.record import plan` is fine; `impactlab.record.recorder` is not."""
    bad = []
    for name, path in MODULES.items():
        user = _owner(name)
        if user not in ("impactlab.calibrate", "impactlab.lab", "impactlab.testing"):
            continue
        for imported in _imports(name, path):
            owner = _owner(imported)
            inside = owner in FACES and owner != user and imported != owner
            if inside and imported not in _face_names(owner):
                bad.append(f"{name} imports {imported}")
    assert not bad, "\n".join(bad)


def _face_names(package: str) -> set[str]:
    """`package.X` for every public name the package's `__init__` defines or exports."""
    tree = ast.parse(MODULES[package].read_text())
    names = {n.name for n in tree.body if isinstance(n, ast.FunctionDef | ast.ClassDef)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Dict):
            names |= {k.value for k in node.keys if isinstance(k, ast.Constant)}
    return {f"{package}.{n}" for n in names}


def test_only_the_command_line_imports_the_top_package():
    """`impactlab` (the API) stands above the stages: none of them imports it back."""
    above = ("impactlab.cli", "impactlab.lab", "impactlab.__main__")
    back = sorted(
        name
        for name, path in MODULES.items()
        if name != "impactlab"
        and not name.startswith(above)
        and "impactlab" in _imports(name, path)
    )
    assert back == []


ANALYZE_LAYERS = ("measure", "tables", "report")
"""The analysis' layers in the data's order: each imports only the layers before it, and none
imports the job modules at the package's top (job, batch, write, publish, view)."""


@pytest.mark.parametrize("layer", ANALYZE_LAYERS)
def test_analyze_layers_import_only_the_layers_before_them(layer: str):
    mine = f"impactlab.analyze.{layer}"
    allowed = {f"impactlab.analyze.{x}" for x in ANALYZE_LAYERS[: ANALYZE_LAYERS.index(layer) + 1]}
    bad = []
    for module, imported in GRAPH.items():
        if module != mine and not module.startswith(mine + "."):
            continue
        for m in imported:
            if not m.startswith("impactlab.analyze"):
                continue
            if m == "impactlab.analyze" or not any(
                m == a or m.startswith(a + ".") for a in allowed
            ):
                bad.append(f"{module} -> {m}")
    assert not bad, bad


def test_base_modules_import_no_stage():
    for base in BASE:
        name = f"impactlab.{base}"
        imported = {_owner(m) for m in _imports(name, MODULES[name]) if m.startswith("impactlab.")}
        assert imported <= {f"impactlab.{b}" for b in BASE} | {"impactlab.errors"}, (name, imported)


def test_help_and_info_import_no_heavy_library(tmp_path):
    """The command line starts fast: building the parser imports no heavy library."""
    code = (
        "import sys; from impactlab.cli import build_parser; build_parser()\n"
        "import impactlab.tools.info\n"
        "heavy = ('mujoco', 'polars', 'matplotlib', 'rerun')\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


@pytest.mark.parametrize("argv", [["--help"], ["info", "GOLDEN"]], ids=["help", "info"])
def test_commands_that_need_no_heavy_library_import_none(argv):
    """Running `impactlab --help` and `impactlab info LOG` imports no matplotlib, rerun or polars."""
    golden = Path(__file__).parent / "golden" / "format1" / "drop_restitution.mcap"
    argv = [str(golden) if a == "GOLDEN" else a for a in argv]
    code = (
        "import runpy, sys\n"
        f"sys.argv = ['impactlab', *{argv!r}]\n"
        "try:\n"
        "    runpy.run_module('impactlab', run_name='__main__')\n"
        "except SystemExit as exit:\n"
        "    code = exit.code\n"
        "heavy = ('polars', 'matplotlib', 'rerun')\n"
        "print(code, sorted(m for m in sys.modules if m.split('.')[0] in heavy), file=sys.stderr)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip(), "the command printed nothing"
    assert out.stderr.strip().splitlines()[-1] in ("0 []", "None []"), out.stderr
