"""Automatic contact / free-flight separation of tangent magnitudes (Fig. 8)."""

import numpy as np
import pytest

from stiffnet.errors import ConfigError, SignalError
from stiffnet.geometry import (
    log_magnitude_histogram,
    otsu_curve,
    otsu_threshold,
    separate_contact,
    tangent_magnitudes,
    tangent_vectors,
)
from stiffnet.nlts import delay_embed


def _two_modes(rng, n_free=9000, n_contact=1000, ratio=10.0):
    free = rng.lognormal(0.0, 0.25, n_free)
    contact = rng.lognormal(np.log(ratio), 0.4, n_contact)
    return np.concatenate([free, contact]), np.r_[np.zeros(n_free, bool), np.ones(n_contact, bool)]


def test_otsu_cut_lies_between_two_modes():
    mags, truth = _two_modes(np.random.default_rng(0))
    sep = separate_contact(mags)
    assert sep.contact_detected
    assert 1.3 < sep.threshold < 5.0  # between the modes at 1 and 10
    assert np.mean(sep.mask == truth) > 0.99
    assert sep.contact_fraction == pytest.approx(0.1, abs=0.01)
    assert sep.mode_ratio == pytest.approx(10.0, rel=0.15)
    assert sep.counts.sum() == mags.size and sep.edges.size == sep.counts.size + 1


def test_gain_moves_the_threshold_and_keeps_the_mask():
    mags, _ = _two_modes(np.random.default_rng(1))
    a, b = separate_contact(mags), separate_contact(1000.0 * mags)
    assert b.threshold == pytest.approx(1000.0 * a.threshold, rel=1e-9)
    np.testing.assert_array_equal(a.mask, b.mask)


def test_unimodal_distribution_is_not_forced_into_two_classes():
    mags = np.random.default_rng(2).lognormal(0.0, 0.3, 5000)
    sep = separate_contact(mags)
    assert not sep.contact_detected
    assert not sep.mask.any() and sep.threshold == np.inf
    assert np.isfinite(sep.otsu_threshold)  # the rejected candidate is still reported
    assert "one mode" in sep.reason


def test_non_impacting_orbit_has_one_mode():
    # The free (linear) response: an ellipse, whose tangent speed varies little.
    t = np.arange(6000)
    s = np.sin(2 * np.pi * t / 95.2)
    sep = separate_contact(tangent_magnitudes(tangent_vectors(delay_embed(s, 3, 17), 1)))
    assert not sep.contact_detected and sep.mode_ratio < 1.2
    # unsmoothed noise of 2 % of the amplitude widens the mode but does not split it
    s = s + 0.02 * np.random.default_rng(3).standard_normal(t.size)
    sep = separate_contact(tangent_magnitudes(tangent_vectors(delay_embed(s, 3, 17), 1)))
    assert not sep.contact_detected


def test_otsu_on_a_two_bin_histogram():
    thr, eta = otsu_threshold([5, 5], [0.0, 1.0, 2.0])
    assert thr == 1.0 and eta == pytest.approx(1.0)
    assert otsu_curve([1, 0, 1], [0, 1, 2, 3]).shape == (2,)


def test_histogram_is_on_log10_and_floors_zeros():
    counts, edges, lm = log_magnitude_histogram(np.array([0.0, 1.0, 10.0, 100.0]), bins=4)
    assert lm[1:].tolist() == [0.0, 1.0, 2.0]
    assert np.isfinite(lm[0]) and counts.sum() == 4


def test_bad_magnitudes():
    with pytest.raises(SignalError, match="zero"):
        separate_contact(np.zeros(10))
    with pytest.raises(SignalError, match="non-negative"):
        separate_contact(np.array([1.0, -1.0, 2.0]))
    with pytest.raises(ConfigError):
        separate_contact(np.ones(10), min_mode_ratio=1.0)
