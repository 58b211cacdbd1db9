"""Smoothing and impact detection (sections 2, 3 and 5.1)."""

import numpy as np
import pytest

from stiffnet.errors import ConfigError
from stiffnet.nlts import (
    detect_impacts,
    impact_indicator_derivative,
    impact_indicator_rms,
    savgol_smooth,
)

N = 5000
SPIKES = np.array([400, 1234, 2500, 3999, 4800])
T = np.arange(N)
SINE = np.sin(2 * np.pi * T / 200)


def spiky(height, width=1.5, noise=0.0):
    x = SINE.copy()
    for k in SPIKES:
        x += height * np.exp(-0.5 * ((T - k) / width) ** 2)
    return x + noise * np.random.default_rng(0).standard_normal(N)


def test_savgol_keeps_quadratics_and_reduces_noise():
    q = 1e-4 * (T - 2000.0) ** 2
    np.testing.assert_allclose(savgol_smooth(q, 11), q, atol=1e-9)
    noisy = spiky(0.0, noise=0.1)
    residual = savgol_smooth(noisy, 21) - SINE
    assert residual.std() < 0.5 * 0.1


@pytest.mark.parametrize(("window", "order"), [(5, 2), (17, 2), (101, 2), (33, 3), (9, 0)])
def test_savgol_is_scipys_interp_mode_to_rounding(window, order):
    """The kept edge operators give scipy's mode="interp" (a polynomial fitted to each end's
    window): the interior bit for bit, the edges to rounding."""
    from scipy.signal import savgol_filter

    x = spiky(3.0, noise=0.2)[:1000] + 1e-3 * (T[:1000] - 400.0) ** 2
    got, want = savgol_smooth(x, window, order), savgol_filter(x, window, order, mode="interp")
    half = window // 2
    np.testing.assert_array_equal(got[half:-half], want[half:-half])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13 * np.abs(want).max())
    # a quadratic's ends are the quadratic itself
    q = 1e-2 * (T[:200] - 30.0) ** 2
    np.testing.assert_allclose(savgol_smooth(q, window, max(order, 2)), q, atol=1e-9)


def test_savgol_rejects_even_window():
    with pytest.raises(ConfigError, match="odd"):
        savgol_smooth(SINE, 10)


@pytest.mark.parametrize("method", ["derivative", "rms"])
def test_spikes_found_within_two_samples(method):
    found = detect_impacts(spiky(5.0, noise=0.02), method=method)
    assert found.size == SPIKES.size
    assert np.all(np.abs(found - SPIKES) <= 2)


def test_derivative_rule_sees_spikes_smaller_than_the_forced_response():
    # spikes of height 1.5 on a unit sine: visible in da/dt, not in (x - mean)^2
    x = spiky(1.5, noise=0.01)
    found = detect_impacts(savgol_smooth(x, 5), fs=1000.0)
    assert np.all(np.abs(found - SPIKES) <= 2) and found.size == SPIKES.size
    assert detect_impacts(x, method="rms").size < SPIKES.size


@pytest.mark.parametrize("method", ["derivative", "rms"])
def test_plain_sine_has_no_impacts(method):
    assert detect_impacts(SINE, method=method).size == 0
    noisy = SINE + 0.02 * np.random.default_rng(1).standard_normal(N)
    assert detect_impacts(noisy, method=method).size == 0


def test_indicators_and_explicit_threshold():
    x = spiky(5.0)
    d = impact_indicator_derivative(x, fs=100.0)
    np.testing.assert_allclose(d, 100.0 * np.abs(np.gradient(x)))
    np.testing.assert_allclose(impact_indicator_rms(x), (x - x.mean()) ** 2)
    # an explicit threshold above every indicator value finds nothing
    assert detect_impacts(x, method="rms", threshold=1e9).size == 0


def test_min_separation_merges_one_contact():
    x = spiky(5.0)
    both_flanks = detect_impacts(x, min_separation=1)
    assert both_flanks.size == 2 * SPIKES.size  # rising and falling flank of each spike
    assert detect_impacts(x).size == SPIKES.size


def test_unknown_method():
    with pytest.raises(ConfigError, match="unknown impact method"):
        detect_impacts(SINE, method="wavelet")
