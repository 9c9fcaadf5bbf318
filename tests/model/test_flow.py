"""Background elongational flow u_inf (Sec. II B, Fig. 1, eq. 29)."""

import numpy as np
import pytest

from vesicle_core.errors import ConfigError
from vesicle_core.model.flow import background_velocity, flow_sign, rate_at


def test_background_velocity_is_planar_extension():
    X = np.array([[1.0, 2.0, 3.0], [-0.5, 0.25, -1.0]])
    u = background_velocity(X, 2.0)
    np.testing.assert_array_equal(u, [[2.0, -4.0, 0.0], [-1.0, -0.5, 0.0]])
    assert u is not X and np.all(X[0] == [1.0, 2.0, 3.0])  # input untouched
    # divergence-free and linear: u(a X) = a u(X)
    np.testing.assert_allclose(background_velocity(3 * X, 2.0), 3 * u)


def test_background_velocity_integer_input_and_shape_check():
    u = background_velocity(np.array([[1, 1, 1]]), 0.5)
    assert u.dtype == np.float64
    np.testing.assert_array_equal(u, [[0.5, -0.5, 0.0]])
    with pytest.raises(ConfigError):
        background_velocity(np.zeros((4, 2)), 1.0)


def test_flow_sign_and_rate_reverse_at_t0():
    assert flow_sign(0.0, 1.0) == 1.0
    assert flow_sign(0.999, 1.0) == 1.0
    assert flow_sign(1.0, 1.0) == -1.0  # from the reversal on
    assert flow_sign(5.0, 1.0) == -1.0
    assert flow_sign(5.0, None) == 1.0
    np.testing.assert_array_equal(flow_sign(np.array([0.0, 2.0]), 1.0), [1.0, -1.0])
    assert rate_at(0.5, 67.0, 1.0) == 67.0
    assert rate_at(1.5, 67.0, 1.0) == -67.0
    # after the reversal the flow is u = -chi (x, -y, 0): compression along x (Fig. 1b)
    u = background_velocity(np.array([[1.0, 1.0, 0.0]]), rate_at(2.0, 67.0, 1.0))
    np.testing.assert_array_equal(u, [[-67.0, 67.0, 0.0]])
