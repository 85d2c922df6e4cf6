"""Golden regression tests of a model's physics for users of impactlab (docs/golden-tests.md):
the pytest plugin (`pytest_plugin`) and the physics compared (`golden_physics`)."""
