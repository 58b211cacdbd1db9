"""Input validation and delay embedding."""

import numpy as np
import pytest

from stiffnet.errors import ConfigError, SignalError
from stiffnet.nlts import as_signal, delay_embed


def test_as_signal_returns_float64_1d():
    out = as_signal([1, 2, 3, 5], min_len=4)
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, [1.0, 2.0, 3.0, 5.0])


@pytest.mark.parametrize(
    ("x", "min_len", "words"),
    [
        (np.ones(50), 10, "constant"),
        (np.r_[np.arange(20.0), np.nan], 10, "NaN"),
        (np.r_[np.arange(20.0), np.inf], 10, "inf"),
        (np.arange(5.0), 10, "too short"),
        (np.arange(20.0).reshape(4, 5), 2, "1-D"),
        (["a", "b", "c"], 2, "numeric"),
        (np.exp(1j * np.arange(20.0)), 2, "complex"),
    ],
)
def test_as_signal_rejects_bad_input_with_named_problem(x, min_len, words):
    with pytest.raises(SignalError, match=words) as info:
        as_signal(x, min_len, name="accel")
    msg = str(info.value)
    assert "accel" in msg
    assert "\n" not in msg  # one-line messages for the CLI
    assert isinstance(info.value, ValueError)


def test_delay_embed_shape_and_values():
    x = np.arange(10.0)
    y = delay_embed(x, dim=3, tau=2)
    assert y.shape == (10 - 2 * 2, 3)
    np.testing.assert_array_equal(y[0], [0.0, 2.0, 4.0])
    np.testing.assert_array_equal(y[-1], [5.0, 7.0, 9.0])
    # every row is (x_i, x_{i+tau}, x_{i+2tau})
    np.testing.assert_array_equal(y[:, 1] - y[:, 0], np.full(6, 2.0))
    assert y.flags.c_contiguous


def test_delay_embed_dim_one_is_the_signal():
    x = np.sin(np.arange(30.0))
    np.testing.assert_array_equal(delay_embed(x, 1, 5)[:, 0], x)


def test_delay_embed_too_short_names_dim_and_tau():
    with pytest.raises(SignalError, match=r"too short.*dim=4, tau=5"):
        delay_embed(np.arange(10.0), dim=4, tau=5)


@pytest.mark.parametrize(("dim", "tau"), [(0, 1), (2, 0), (2.5, 1), (True, 1)])
def test_delay_embed_bad_parameters(dim, tau):
    with pytest.raises(ConfigError):
        delay_embed(np.arange(100.0), dim, tau)


def test_delay_embed_rejects_nan():
    x = np.arange(100.0)
    x[10] = np.nan
    with pytest.raises(SignalError, match="NaN"):
        delay_embed(x, 2, 1)
