"""Generate the Python bindings in this folder from the .proto sources in `schemas/`.

Run as `python -m impactlab.proto.generate` (or `just schemas`). Needs grpcio-tools (a dev
dependency); the generated files are committed, and a test fails when they are stale.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]
SCHEMA_DIR = REPO_ROOT / "schemas"
OUT_DIR = Path(__file__).resolve().parent


def generate(out_dir: Path) -> list[Path]:
    """Compile every `schemas/*.proto` into `*_pb2.py` and `*_pb2.pyi` under `out_dir`."""
    from grpc_tools import protoc

    protos = sorted(p.name for p in SCHEMA_DIR.glob("*.proto"))
    args = ["protoc", f"-I{SCHEMA_DIR}", f"--python_out={out_dir}", f"--pyi_out={out_dir}", *protos]
    if protoc.main(args) != 0:
        raise RuntimeError(f"protoc failed on {protos}")
    return sorted(out_dir.glob("*_pb2.py*"))


def stale_files() -> list[str]:
    """Names of generated files that differ from what the schemas generate now."""
    with tempfile.TemporaryDirectory() as tmp:
        fresh = {p.name: p.read_bytes() for p in generate(Path(tmp))}
    committed = {p.name: p.read_bytes() for p in OUT_DIR.glob("*_pb2.py*")}
    names = sorted(set(fresh) | set(committed))
    return [n for n in names if fresh.get(n) != committed.get(n)]


def main() -> int:
    """Regenerate the committed bindings; one error line and exit 2 outside a checkout."""
    if not any(SCHEMA_DIR.glob("*.proto")):
        print(
            f"impactlab.proto.generate: error: {SCHEMA_DIR}: no *.proto there: this regenerates "
            "the bindings in a checkout of impactlab (schemas/); run it there",
            file=sys.stderr,
        )
        return 2
    try:
        import grpc_tools  # noqa: F401
    except ImportError:
        print(
            "impactlab.proto.generate: error: needs grpcio-tools (pip install -e '.[test]')",
            file=sys.stderr,
        )
        return 2
    for path in generate(OUT_DIR):
        print(f"wrote {path.relative_to(REPO_ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
