"""`impactlab examples [DIR]`: copy the handout's experiment specs out of the package to edit."""

from __future__ import annotations

import argparse
from pathlib import Path

from impactlab.cli.options import path


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the `examples` subcommand."""
    p = sub.add_parser(
        "examples",
        help="copy the handout's experiment specs into a folder, to read and edit",
        description="Copy the experiment specs that ship with impactlab (the ones `impactlab "
        "lab` runs when there is no experiments/ folder here) into DIR. Nothing is "
        "overwritten. Then `impactlab lab` (for DIR = experiments) or `impactlab lab "
        "--experiments DIR` runs the copies, and `impactlab record DIR/drop.toml` one of them.",
    )
    p.add_argument(
        "dir",
        nargs="?",
        type=path,
        default=Path("experiments"),
        metavar="DIR",
        help="folder to copy them into (experiments/)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Copy the specs; print what was written."""
    from impactlab.examples import copy_examples, packaged_experiments

    written = copy_examples(args.dir)
    print(f"copied {len(written)} experiment spec(s) from {packaged_experiments()} to {args.dir}/:")
    for spec in written:
        print(f"  {spec}")
    where = "" if args.dir == Path("experiments") else f" --experiments {args.dir}"
    print(f"run them with: impactlab lab{where}")
    return 0
