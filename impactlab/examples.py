"""The handout's experiment specs, shipped with impactlab, and copies of them to edit.

A checkout keeps them in `experiments/` at the repository root (the source of truth); a wheel
packages that folder as `impactlab/experiments/` (setup.py). `impactlab lab` runs them when the
working folder has no `experiments/` of its own, and `impactlab examples DIR` copies them out.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from impactlab.errors import ImpactlabError
from impactlab.files import OutputError, atomic_path

PACKAGED = Path(__file__).resolve().with_name("experiments")  # an installed impactlab
CHECKOUT = Path(__file__).resolve().parents[1] / "experiments"  # a clone (no install, or -e)


def packaged_experiments() -> Path:
    """The folder of the handout's specs: the installed package's, else the checkout's.

    Raises:
        ImpactlabError: neither holds a spec (an install without its package data).
    """
    if any(PACKAGED.glob("*.toml")):
        return PACKAGED
    if (CHECKOUT.parent / "pyproject.toml").is_file() and any(CHECKOUT.glob("*.toml")):
        return CHECKOUT
    raise ImpactlabError(
        f"{PACKAGED}: no experiment specs: this impactlab was installed without its package "
        "data (reinstall it: pip install --force-reinstall impactlab)"
    )


def example_specs() -> list[Path]:
    """The handout's specs (`*.toml`), sorted by name."""
    return sorted(packaged_experiments().glob("*.toml"))


def copy_examples(dest: Path) -> list[Path]:
    """Copy the handout's specs into `dest` (created); returns the files written.

    Nothing is overwritten: when a spec of that name is in `dest` already, nothing is copied.

    Raises:
        OutputError: `dest` is not a folder, cannot be written, or holds a spec of that name.
    """
    specs = example_specs()
    if dest.exists() and not dest.is_dir():
        raise OutputError(dest, "exists and is not a folder")
    taken = [dest / s.name for s in specs if (dest / s.name).exists()]
    if taken:
        raise OutputError(
            taken[0], f"exists already ({len(taken)} of the {len(specs)} specs do); nothing copied"
        )
    created = not dest.exists()
    written: list[Path] = []
    try:
        dest.mkdir(parents=True, exist_ok=True)
        for spec in specs:
            with atomic_path(dest / spec.name) as tmp:
                shutil.copyfile(spec, tmp)
            written.append(dest / spec.name)
    except OSError as exc:  # nothing half-copied stays
        for path in written:
            path.unlink(missing_ok=True)
        if created:
            shutil.rmtree(dest, ignore_errors=True)
        raise OutputError(dest, f"cannot write there: {exc.strerror or exc}") from None
    return written
