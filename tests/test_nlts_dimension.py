"""Embedding dimension: false nearest neighbours and Cao's method (eq. 3)."""

import numpy as np
import pytest
from _lorenz import lorenz_x
from scipy.spatial.distance import cdist

from stiffnet.errors import ConfigError, SignalError
from stiffnet.nlts import (
    cao_curves,
    cao_dimension,
    estimate_dimension,
    false_nearest_neighbours,
    fnn_dimension,
)
from stiffnet.nlts._neighbours import nearest_outside_window


@pytest.fixture(scope="module")
def lorenz():
    return lorenz_x(5000)


def test_cao_on_a_line_saturates_at_one_immediately():
    # A ramp embeds on a straight line: neighbour distances never change with d.
    e1, e2 = cao_curves(np.arange(2000.0), tau=1, max_dim=6)
    np.testing.assert_allclose(e1, 1.0, atol=1e-9)
    np.testing.assert_allclose(e2, 1.0, atol=1e-9)
    assert cao_dimension(e1) == 1


def test_cao_on_sine_gives_two():
    t = np.arange(5000)
    x = np.sin(2 * np.pi * t / (20 * np.pi))  # irrational period: no exact repeats
    e1, _ = cao_curves(x, tau=16, max_dim=6)
    assert e1[0] < 0.1  # 1-D: neighbours on the up and down swing are false
    np.testing.assert_allclose(e1[1:], 1.0, atol=0.01)
    assert cao_dimension(e1) == 2


def test_cao_exactly_periodic_sine_ignores_rounding_error_duplicates():
    # period 100.3 samples repeats exactly every 1003 samples, up to rounding error
    x = np.sin(2 * np.pi * np.arange(5000) / 100.3)
    e1, _ = cao_curves(x, tau=25, max_dim=5)
    assert cao_dimension(e1) == 2


def test_cao_on_lorenz_gives_three(lorenz):
    e1, e2 = cao_curves(lorenz, tau=17, max_dim=6)
    assert e1.shape == e2.shape == (6,)
    assert e1[1] < 0.5 < 0.9 < e1[2]
    assert cao_dimension(e1) == 3
    # deterministic data: E2 is not constant 1
    assert np.max(np.abs(e2 - 1)) > 0.3


def test_cao_e2_of_noise_is_near_one():
    x = np.random.default_rng(0).standard_normal(3000)
    _, e2 = cao_curves(x, tau=1, max_dim=5)
    np.testing.assert_allclose(e2, 1.0, atol=0.1)


def test_fnn_on_lorenz_drops_to_zero_by_three(lorenz):
    f = false_nearest_neighbours(lorenz, tau=17, max_dim=5)
    assert f[0] > 0.9
    assert f[2] < 0.01
    assert fnn_dimension(f) == 3


def test_fnn_size_test_keeps_noise_false():
    # Test I alone lets noise look embedded at m ~ 5 (neighbour gaps stop growing);
    # Kennel's test II (R_{m+1} / R_A > 2) keeps flagging its distant neighbours.
    x = np.random.default_rng(0).standard_normal(3000)
    with_size_test = false_nearest_neighbours(x, tau=1, max_dim=6)
    distance_only = false_nearest_neighbours(x, tau=1, max_dim=6, atol=np.inf)
    assert distance_only[-1] < 0.01
    assert np.all(with_size_test[3:] > 0.1)


def test_fnn_rule_raises_when_never_below_threshold():
    with pytest.raises(SignalError, match="never falls"):
        fnn_dimension([0.9, 0.5, 0.2, 0.1], threshold=0.01)


def test_estimate_dimension_methods_agree_on_lorenz(lorenz):
    assert estimate_dimension(lorenz, 17, max_dim=6) == (3, "cao_dimension")
    assert estimate_dimension(lorenz, 17, max_dim=6, method="fnn") == (3, "fnn_dimension")


def test_too_short_signal_raises():
    with pytest.raises(SignalError, match="too short"):
        cao_curves(np.random.default_rng(0).standard_normal(100), tau=10, max_dim=10)


@pytest.mark.parametrize("p", [2.0, np.inf])
def test_staged_kdtree_search_matches_brute_force(p):
    rng = np.random.default_rng(3)
    # a smooth trajectory: temporal neighbours are the closest points
    t = np.arange(600)
    y = np.c_[np.sin(t / 7), np.cos(t / 11)] + 0.01 * rng.standard_normal((600, 2))
    w, k = 5, 3
    dist, idx = nearest_outside_window(y, w, p=p, k=k)
    d = cdist(y, y, "euclidean" if p == 2 else "chebyshev")
    d[np.abs(t[:, None] - t[None, :]) <= w] = np.inf
    order = np.argsort(d, axis=1)[:, :k]
    np.testing.assert_allclose(dist, np.take_along_axis(d, order, axis=1))
    assert np.all(np.abs(idx - t[:, None]) > w)


def per_dimension_reference(x, tau, top, theiler, p):
    """E-curves' raw material the plain way: one staged tree search per dimension."""
    tiny = 1e-10 * float(np.ptp(x))
    for m in range(1, top + 1):
        n = x.size - m * tau
        y = np.lib.stride_tricks.sliding_window_view(x[: n + (m - 1) * tau], (m - 1) * tau + 1)
        dist, idx = nearest_outside_window(y[:, ::tau].copy(), theiler, p=p, min_dist=tiny)
        nxt = x[m * tau :]
        yield dist[:, 0], np.abs(nxt - nxt[idx[:, 0]])


def reference_cao(x, tau, max_dim, theiler, p):
    e, es = [], []
    for dist, extra in per_dimension_reference(x, tau, max_dim + 1, theiler, p):
        grown = np.maximum(dist, extra) if p == np.inf else np.hypot(dist, extra)
        e.append(np.mean(grown / dist))
        es.append(np.mean(extra))
    e, es = np.array(e), np.array(es)
    return e[1:] / e[:-1], es[1:] / es[:-1]


def reference_fnn(x, tau, max_dim, theiler, rtol=15.0, atol=2.0):
    return np.array(
        [
            np.mean((extra > rtol * dist) | (np.hypot(dist, extra) > atol * x.std()))
            for dist, extra in per_dimension_reference(x, tau, max_dim, theiler, 2.0)
        ]
    )


@pytest.mark.parametrize(
    "signal",
    ["lorenz", "quantised lorenz", "noise", "periodic sine", "ramp"],
)
def test_carried_neighbours_give_the_per_dimension_search_bit_for_bit(signal, lorenz):
    # Cao (maximum norm) carries certified neighbours from one dimension to the
    # next and searches 1-D by sorting; the curves must not change in the last bit.
    x = {
        "lorenz": lorenz,
        "quantised lorenz": np.round(lorenz[:3000] * 4) / 4,  # ties everywhere
        "noise": np.random.default_rng(4).standard_normal(2000),
        "periodic sine": np.sin(2 * np.pi * np.arange(3000) / 100.3),
        "ramp": np.arange(1500.0),
    }[signal]
    for tau, theiler in [(17, 10), (3, None)]:
        w = tau if theiler is None else theiler
        for metric, p in [("chebyshev", np.inf), ("euclidean", 2.0)]:
            e1, e2 = cao_curves(x, tau, 8, theiler=theiler, metric=metric)
            r1, r2 = reference_cao(x, tau, 8, w, p)
            np.testing.assert_array_equal(e1, r1)
            np.testing.assert_array_equal(e2, r2)
        f = false_nearest_neighbours(x, tau, 8, theiler=theiler)
        np.testing.assert_array_equal(f, reference_fnn(x, tau, 8, w))


def _tisean_fnn_brute_force(x, tau, max_dim, rt, theiler):
    """TISEAN false_nearest's definition, written out with O(N^2) loops over pairs.

    Reference points i < N - M tau, candidates j < N - (M + 1) tau (M = max_dim),
    |i - j| > theiler, maximum norm, distance 0 skipped; a pair counts when its
    distance is <= std / rt and is false when the next coordinate differs by more
    than rt times the distance; fraction = false / counted.
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    n_ref, n_cand = n - max_dim * tau, n - (max_dim + 1) * tau
    sigma = np.sqrt(np.mean(x**2) - np.mean(x) ** 2)
    i, j = np.arange(n_ref)[:, None], np.arange(n_cand)[None, :]
    out = []
    for m in range(1, max_dim + 1):  # all pairs at once: an (n_ref, n_cand) matrix
        d = np.max([np.abs(x[i + k * tau] - x[j + k * tau]) for k in range(m)], axis=0)
        d[(np.abs(i - j) <= theiler) | (d == 0.0)] = np.inf
        which = np.argmin(d, axis=1)
        best = d[np.arange(n_ref), which]
        counted = best <= sigma / rt
        gap = np.abs(x[np.arange(n_ref) + m * tau] - x[which + m * tau])
        false = (gap / best > rt) & counted
        out.append(false.sum() / counted.sum() if counted.any() else np.nan)
    return np.array(out)


@pytest.mark.parametrize(("rt", "theiler"), [(2.0, 0), (3.0, 4)])
def test_fnn_max_norm_reproduces_tisean_definition(rt, theiler):
    x = lorenz_x(600, dt=0.05)
    got = false_nearest_neighbours(x, 2, max_dim=4, rtol=rt, theiler=theiler, norm="max")
    want = _tisean_fnn_brute_force(x, 2, 4, rt, theiler)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert np.isfinite(want).all() and want[0] > want[-1]  # a meaningful check
    # and it is not the default (Kennel's, Euclidean) definition
    default = false_nearest_neighbours(x, 2, max_dim=4, rtol=rt, theiler=theiler)
    assert not np.allclose(default, want)


def test_fnn_norm_is_checked():
    with pytest.raises(ConfigError, match="norm"):
        false_nearest_neighbours(np.sin(np.arange(500) / 5), 3, norm="manhattan")
