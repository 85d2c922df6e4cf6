"""Testing helpers for users of impactlab: golden regression tests of a model's physics.

Owns: the pytest plugin (`pytest_plugin`: the `impactlab_golden` fixture and the
`--impactlab-update-golden` flag, registered through the `pytest11` entry point) and the
comparison of two recordings' physics from their analysis tables (`golden_physics`).
See docs/golden-tests.md.

May import: the public faces of `impactlab.record` and `impactlab.analyze`, `impactlab.logs`,
pytest. Must not import: `impactlab.replay`, `impactlab.calibrate`, the command line. Nothing
in impactlab imports this package.
"""
