"""One up vector for the recorder and the analysis (`impactlab.physics.up_vector`): against
gravity, unit length, +z when there is none or no float holds its norm."""

from __future__ import annotations

import numpy as np
import pytest

from impactlab.physics import up_vector


@pytest.mark.parametrize(
    ("gravity", "up"),
    [
        ([0.0, 0.0, -9.81], [0.0, 0.0, 1.0]),
        ([3.0, -4.0, 0.0], [-0.6, 0.8, 0.0]),
        ([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ([0.0, 1e300, -1e300], [0.0, -(0.5**0.5), 0.5**0.5]),  # the norm alone overflows
        ([np.inf, 0.0, 0.0], [0.0, 0.0, 1.0]),
    ],
)
def test_up_vector(gravity, up):
    np.testing.assert_allclose(up_vector(np.array(gravity)), up, rtol=0, atol=1e-15)
