"""Cross-prediction stationarity test (section 4.2.1)."""

import numpy as np
import pytest

from stiffnet.errors import ConfigError
from stiffnet.nlts import cross_prediction_errors, is_stationary

N = 4000


def noisy(x, seed):
    return x + 0.1 * np.random.default_rng(seed).standard_normal(x.size)


def test_stationary_sine_is_stationary():
    t = np.arange(N)
    s = cross_prediction_errors(noisy(np.sin(2 * np.pi * t / 50), 0), dim=3, tau=12)
    assert s.shape == (4, 4)
    # every entry is about the noise level (0.1 / 0.71 = 0.14 of the std)
    assert np.all((s > 0.1) & (s < 0.3))
    assert s.max() / s.min() < 1.3
    assert is_stationary(s)


def test_frequency_change_halfway_is_not_stationary():
    t = np.arange(N)
    phase = 2 * np.pi * np.cumsum(np.where(t < N // 2, 1 / 50, 1 / 35))
    s = cross_prediction_errors(noisy(np.sin(phase), 1), dim=3, tau=12)
    # halves predict themselves at the noise level, each other much worse
    within = np.r_[s[:2, :2].ravel(), s[2:, 2:].ravel()]
    across = np.r_[s[:2, 2:].ravel(), s[2:, :2].ravel()]
    assert across.min() > 2 * within.max()
    assert not is_stationary(s)


def test_self_prediction_cannot_copy_the_previous_samples():
    # A random walk never recurs: a segment can predict itself only from its own
    # immediate past, which the Theiler window excludes, so the error must stay
    # well above that of persistence (x_{t+1} = x_t).
    rw = np.cumsum(np.random.default_rng(0).standard_normal(N))
    s = cross_prediction_errors(rw, dim=3, tau=12)
    persistence = np.sqrt(np.mean(np.diff(rw) ** 2)) / rw.std()
    assert np.diag(s).min() > 1.5 * persistence
    assert not is_stationary(s)


def test_rule_uses_floor_for_near_perfect_predictions():
    s = np.array([[0.001, 0.003], [0.002, 0.001]])
    assert is_stationary(s)  # 3x ratio of errors far below the noise floor
    assert not is_stationary(s, floor=0.0)


def test_rule_rejects_non_square():
    with pytest.raises(ConfigError):
        is_stationary(np.ones((2, 3)))


def _cross_prediction_brute_force(x, dim, tau, n_seg, k, theiler, p, per_segment):
    """The documented definition with explicit distance matrices (no tree)."""
    x = np.asarray(x, dtype=float)
    length = x.size // n_seg
    span = (dim - 1) * tau
    segs = [x[s * length : (s + 1) * length] for s in range(n_seg)]
    vec = [np.column_stack([g[q * tau : length - 1 - span + q * tau] for q in range(dim)])
           for g in segs]  # fmt: skip
    fut = [g[span + 1 :] for g in segs]
    out = np.empty((n_seg, n_seg))
    for i in range(n_seg):
        for j in range(n_seg):
            diff = np.abs(vec[j][:, None, :] - vec[i][None, :, :])
            d = diff.max(axis=2) if p == "max" else np.sqrt((diff**2).sum(axis=2))
            if i == j:
                t = np.arange(len(vec[i]))
                d[np.abs(t[:, None] - t[None, :]) <= theiler] = np.inf
            nn = np.argsort(d, axis=1, kind="stable")[:, :k]
            err = np.sqrt(np.mean((fut[i][nn].mean(axis=1) - fut[j]) ** 2))
            out[i, j] = err / (segs[j].std() if per_segment else x.std())
    return out


@pytest.mark.parametrize(("norm", "scale"), [("max", "segment"), ("euclidean", "signal")])
def test_cross_prediction_norm_and_scale_follow_their_definition(norm, scale):
    rng = np.random.default_rng(4)
    t = np.arange(1200)
    x = np.sin(0.13 * t) + 0.4 * np.sin(0.031 * t) * (t > 600) + 0.05 * rng.standard_normal(t.size)
    got = cross_prediction_errors(x, 3, 4, n_segments=3, n_neighbours=4, norm=norm, scale=scale)
    want = _cross_prediction_brute_force(x, 3, 4, 3, 4, 2 * 4 + 1, norm, scale == "segment")
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_cross_prediction_tisean_options_change_the_numbers():
    x = np.sin(0.13 * np.arange(1200)) * (1 + 0.5 * (np.arange(1200) > 800))
    base = cross_prediction_errors(x, 3, 4, n_segments=3)
    tisean = cross_prediction_errors(x, 3, 4, n_segments=3, norm="max", scale="segment")
    assert not np.allclose(base, tisean)
    with pytest.raises(ConfigError, match="scale"):
        cross_prediction_errors(x, 3, 4, scale="range")
