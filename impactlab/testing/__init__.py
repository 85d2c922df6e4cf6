"""Golden regression tests of a model's physics for users (docs/golden-tests.md)."""
