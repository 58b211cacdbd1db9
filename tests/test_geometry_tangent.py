"""Tangent vectors of the embedded trajectory (paper eqs 4-6)."""

import numpy as np
import pytest

from stiffnet.errors import ConfigError, SignalError
from stiffnet.geometry import tangent_lag, tangent_magnitudes, tangent_vectors
from stiffnet.nlts import delay_embed


def test_tangent_is_difference_of_points_n_apart():
    # V(N - n) = Y(N) - Y(N - n), coordinate by coordinate (eqs 4-6)
    y = np.arange(30, dtype=float).reshape(10, 3) ** 2
    v = tangent_vectors(y, lag=2)
    assert v.shape == (8, 3)
    np.testing.assert_array_equal(v[3], y[5] - y[3])


def test_delay_coordinates_are_shifted_increments():
    s = np.sin(np.arange(200) / 7.0) + 0.1 * np.arange(200) ** 0.5
    tau, n = 5, 2
    v = tangent_vectors(delay_embed(s, 3, tau), n)
    d = s[n:] - s[:-n]
    np.testing.assert_allclose(v[:, 0], d[: v.shape[0]])
    np.testing.assert_allclose(v[:, 2], d[2 * tau : 2 * tau + v.shape[0]])


def test_magnitudes_use_first_three_coordinates_by_default():
    v = np.array([[3.0, 4.0, 0.0, 100.0], [0.0, 0.0, 2.0, -7.0]])
    np.testing.assert_allclose(tangent_magnitudes(v), [5.0, 2.0])
    np.testing.assert_allclose(tangent_magnitudes(v, coords=(0, 3)), [np.hypot(3, 100), 7.0])


def test_tangent_lag_scales_with_the_period():
    assert tangent_lag(95.2) == 1  # the paper's sampling
    assert tangent_lag(476.0) == 5
    assert tangent_lag(20.0) == 1  # never below one sample
    with pytest.raises(ConfigError):
        tangent_lag(0.0)


def test_bad_trajectories():
    with pytest.raises(SignalError, match="shape"):
        tangent_vectors(np.zeros(10))
    with pytest.raises(SignalError, match="NaN"):
        tangent_vectors(np.array([[0.0, np.nan], [1.0, 2.0]]))
    with pytest.raises(SignalError, match="too short"):
        tangent_vectors(np.zeros((3, 3)), lag=3)
