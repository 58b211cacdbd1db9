"""Embedding delay: AMI (eq. 2), autocorrelation and the delay rules."""

import numpy as np
import pytest
from _lorenz import lorenz_x

from stiffnet.errors import SignalError
from stiffnet.nlts import (
    autocorrelation,
    autocorrelation_decay_time,
    estimate_delay,
    first_minimum,
    first_prominent_minimum,
    mutual_information,
)

PERIOD = 80
NOISE = 0.3
# For x = sin + noise the ACF at lag k >= 1 is RHO * cos(2 pi k / P).
RHO = 0.5 / (0.5 + NOISE**2)


def sine(n=20000, period=PERIOD, noise=NOISE, seed=0):
    # Some noise on purpose: the binned AMI of a noise-free sine is dominated by
    # grid artefacts (the joint density lives on a curve), its dips wander over
    # lags 2-6; with noise it behaves like -log(1 - rho^2)/2, minimal where the
    # correlation cos(2 pi lag / P) vanishes.
    t = np.arange(n)
    rng = np.random.default_rng(seed)
    return np.sin(2 * np.pi * t / period) + noise * rng.standard_normal(n)


def test_ami_lag_zero_is_entropy_and_curve_decreases_first():
    x = sine()
    ami = mutual_information(x, 40, bins=16)
    assert ami.shape == (41,)
    # lag 0: I(x; x) = H(binned x) <= log(bins), and it is the maximum
    assert ami[0] == pytest.approx(ami.max())
    assert 0.5 * np.log(16) < ami[0] <= np.log(16) + 1e-12
    assert np.all(np.diff(ami[:10]) < 0)


def test_ami_matches_histogram2d_reference():
    x = sine(n=3000)
    ami = mutual_information(x, 30, bins=12)
    edges = np.linspace(x.min(), x.max(), 13)
    for lag in (0, 7, 30):
        joint, _, _ = np.histogram2d(x[: x.size - lag], x[lag:], bins=[edges, edges])
        p = joint / joint.sum()
        outer = np.outer(p.sum(1), p.sum(0))
        nz = p > 0
        assert ami[lag] == pytest.approx(np.sum(p[nz] * np.log(p[nz] / outer[nz])), rel=1e-12)


def test_ami_of_independent_noise_is_small():
    x = np.random.default_rng(1).standard_normal(20000)
    ami = mutual_information(x, 5, bins=8)
    # histogram bias (bins-1)^2 / 2N = 1.2e-3 nats; a dependent pair would be >> 0.01
    assert np.all(ami[1:] < 0.01)


@pytest.mark.parametrize("rule", [first_minimum, first_prominent_minimum])
def test_ami_first_minimum_of_sine_is_quarter_period(rule):
    ami = mutual_information(sine(), 60, bins=16)
    assert abs(rule(ami) - PERIOD / 4) <= 2


def test_acf_of_sine_crosses_zero_at_quarter_period():
    acf = autocorrelation(sine(), 60)
    assert acf[0] == pytest.approx(1.0)
    assert autocorrelation_decay_time(acf, level=0.0) == pytest.approx(PERIOD / 4, abs=1)
    half = np.arccos(0.5 / RHO) / (2 * np.pi) * PERIOD  # first lag with acf <= 0.5
    assert autocorrelation_decay_time(acf, level=0.5) == np.ceil(half)


def test_acf_matches_direct_sum():
    x = np.random.default_rng(2).standard_normal(500)
    acf = autocorrelation(x, 10)
    xc = x - x.mean()
    direct = np.array([np.dot(xc[: x.size - k], xc[k:]) for k in range(11)]) / np.dot(xc, xc)
    np.testing.assert_allclose(acf, direct, atol=1e-12)


def test_first_minimum_handles_plateau_and_reports_first_index():
    assert first_minimum([5.0, 4.0, 3.0, 3.0, 3.0, 4.0, 2.0]) == 2
    assert first_minimum([3.0, 2.0, 2.0, 1.0, 5.0]) == 3  # a flat step is not a minimum


def test_rules_raise_when_no_minimum():
    with pytest.raises(SignalError, match="no local minimum"):
        first_minimum(np.linspace(1, 0, 20))
    with pytest.raises(SignalError, match="no minimum"):
        first_prominent_minimum(np.linspace(1, 0, 20))
    with pytest.raises(SignalError, match="stays above"):
        autocorrelation_decay_time(np.linspace(1, 0.5, 20), level=0.2)


def test_robust_rule_is_stable_over_bin_counts_where_plain_rule_is_not():
    x = sine(n=5000, period=100, noise=0.6)
    bins = [8, 12, 16, 24, 32, 48, 64]
    curves = [mutual_information(x, 150, b) for b in bins]
    robust = np.array([first_prominent_minimum(c) for c in curves])
    plain = np.array([first_minimum(c) for c in curves])
    assert np.ptp(robust) <= 3
    assert np.all(np.abs(robust - 25) <= 3)
    # the plain first minimum is caught by estimator noise at small lags
    assert plain.min() < 10


def test_lorenz_ami_first_minimum_matches_tisean():
    # TISEAN `mutual` with 16 boxes: first minimum at lag 17 for Lorenz x, dt = 0.01.
    x = lorenz_x(20000)
    ami = mutual_information(x, 60, bins=16)
    assert first_minimum(ami) == 17
    assert abs(first_prominent_minimum(ami) - 17) <= 1


def test_estimate_delay_reports_rule_and_falls_back_to_acf():
    x = sine()
    lag, rule = estimate_delay(x, max_lag=60)
    assert abs(lag - PERIOD / 4) <= 2
    assert rule == "ami_first_prominent_minimum"
    lag, rule = estimate_delay(x, method="acf", max_lag=60, level=0.0)
    assert lag == pytest.approx(PERIOD / 4, abs=1) and rule.startswith("acf_decay")
    # up to lag 15 the AMI of this sine only decreases: ACF 1/e decay time instead
    lag, rule = estimate_delay(x, max_lag=15)
    assert "fallback" in rule
    assert lag == np.ceil(np.arccos(1 / np.e / RHO) / (2 * np.pi) * PERIOD)


def test_ami_all_lags_at_once_equals_lag_by_lag_to_the_last_bit():
    rng = np.random.default_rng(3)
    for x, bins in [(lorenz_x(4000), 16), (sine(3000), 7), (np.floor(rng.normal(size=999)), 32)]:
        ami = mutual_information(x, 50, bins)
        b = np.minimum(((x - x.min()) * (bins / np.ptp(x))).astype(np.intp), bins - 1)
        n = x.size
        for lag in range(51):
            joint = np.bincount(b[: n - lag] * bins + b[lag:], minlength=bins * bins)
            p = joint.reshape(bins, bins) / (n - lag)
            nz = p > 0
            outer = np.outer(p.sum(axis=1), p.sum(axis=0))
            assert ami[lag] == np.sum(p[nz] * np.log(p[nz] / outer[nz]))
