"""The package list: every `impactlab*` package, plus the handout's experiment specs.

The specs stay at the repository root (`experiments/`, the source of truth that the README,
the tests and the benchmarks read) and are packaged as `impactlab/experiments/*.toml`, so an
installed impactlab runs them without a checkout (`impactlab lab`, `impactlab examples`).
Everything else is in pyproject.toml.
"""

from setuptools import find_packages, setup

setup(
    packages=[*find_packages(include=["impactlab", "impactlab.*"]), "impactlab.experiments"],
    package_dir={"impactlab.experiments": "experiments"},
)
