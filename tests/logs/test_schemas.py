"""The committed protobuf bindings are what `just schemas` generates from schemas/*.proto."""

import pytest

from impactlab.proto.generate import stale_files

pytestmark = pytest.mark.extras  # grpcio-tools: the schemas extra


def test_generated_bindings_are_fresh():
    stale = stale_files()
    assert not stale, f"regenerate with `just schemas`: stale {stale}"
