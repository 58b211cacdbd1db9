"""Nearest valid neighbours: the sorted 1-D sweep and the certified tree search.

Both must give the answer of the staged KD-tree search (`nearest_outside_window`)
bit for bit, ties included: tied rows go to that search itself.
"""

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from stiffnet.errors import SignalError
from stiffnet.nlts._neighbours import (
    _sorted_search,
    _tree_search,
    nearest_outside_window,
    nearest_valid,
)


def reference(y, theiler, p, min_dist, rows=None):
    rows = np.arange(len(y)) if rows is None else rows
    d, i = nearest_outside_window(
        y, theiler, p=p, queries=y[rows], query_index=rows, min_dist=min_dist
    )
    return d[:, 0], i[:, 0]


@pytest.mark.parametrize("p", [2.0, np.inf])
@pytest.mark.parametrize("theiler", [0, 3, 12])
@pytest.mark.parametrize("min_dist", [0.0, 0.02])
def test_sorted_1d_search_equals_kdtree_with_ties_and_window(p, theiler, min_dist):
    rng = np.random.default_rng(theiler)
    y = rng.random((700, 1)) * 20
    y[::3] = np.round(y[::3] * 2) / 2  # a third on a grid: equal values, equal distances
    y[rng.choice(700, 50)] = y[rng.choice(700, 50)]  # exact copies at other times
    d_ref, i_ref = reference(y, theiler, p, min_dist)
    # The sweep on its own: every row it settles without a tie is the tree's answer.
    rows = np.arange(len(y))
    d, i, bound, tie = _sorted_search(y, rows, theiler, p, min_dist)
    assert 0.05 < tie.mean() < 0.95  # both kinds of rows are there
    np.testing.assert_array_equal(d[~tie], d_ref[~tie])
    np.testing.assert_array_equal(i[~tie], i_ref[~tie])
    # With the tied rows answered by the tree search, everything matches.
    d, i, bound, plain = nearest_valid(y, theiler, p, min_dist)
    np.testing.assert_array_equal(plain, tie)
    np.testing.assert_array_equal(d, d_ref)
    np.testing.assert_array_equal(i, i_ref)


@pytest.mark.parametrize("p", [2.0, np.inf])
@pytest.mark.parametrize("dim", [2, 3])
def test_certified_tree_search_equals_default_tree_search(p, dim):
    rng = np.random.default_rng(dim)
    y = rng.random((900, dim)) * 4
    y[::3] = np.round(y[::3] * 2) / 2  # a third on a grid: distance ties
    y[rng.choice(900, 60)] = y[rng.choice(900, 60)]  # exact copies at other times
    rows = np.sort(rng.choice(len(y), 300, replace=False))
    d_ref, i_ref = reference(y, 4, p, 0.0, rows)
    d, i, bound, tie = _tree_search(y, rows, 4, p, 0.0)
    assert 0.05 < tie.mean() < 0.95
    np.testing.assert_array_equal(d[~tie], d_ref[~tie])
    np.testing.assert_array_equal(i[~tie], i_ref[~tie])
    d, i, bound, _ = nearest_valid(y, 4, p, 0.0, rows)
    np.testing.assert_array_equal(d, d_ref)
    np.testing.assert_array_equal(i, i_ref)


@pytest.mark.parametrize("dim", [1, 3])
@pytest.mark.parametrize("data", ["smooth", "copies"])
def test_bound_separates_every_other_valid_point(dim, data):
    rng = np.random.default_rng(7)
    n, theiler, min_dist = 800, 5, 1e-6
    if data == "smooth":  # a trajectory: temporal neighbours are the closest points
        t = np.arange(n + dim)
        x = np.sin(t / 9) + 0.3 * np.sin(t / 4.1) + 0.01 * rng.standard_normal(t.size)
        y = np.lib.stride_tricks.sliding_window_view(x, dim)[:n].copy()
    else:  # exact copies of other points: duplicates, and ties for their neighbours
        y = rng.random((n, dim))
        y[rng.choice(n, 80, replace=False)] = y[rng.choice(n, 80, replace=False)]
    dist, idx, bound, _ = nearest_valid(y, theiler, np.inf, min_dist)
    d = cdist(y, y, "chebyshev")
    t = np.arange(n)
    d[np.abs(t[:, None] - t[None, :]) <= theiler] = np.inf  # only points outside the window
    certified = bound > dist
    assert certified.mean() > 0.5
    assert certified.all() == (data == "smooth")  # copies: no certificate where one is near
    others = d.copy()
    others[t, idx] = np.inf
    # every other point outside the window is at least `bound` away (duplicates too)
    assert np.all(others[certified].min(axis=1) >= bound[certified])
    assert np.all(bound[~certified] == -np.inf)
    # and the neighbour is the nearest point beyond min_dist
    d[d <= min_dist] = np.inf
    np.testing.assert_array_equal(dist, d.min(axis=1))


def test_only_duplicates_raise_like_the_tree_search():
    y = np.repeat([[0.0], [1.0]], 30, axis=0)  # two values, each a run of 30 samples
    with pytest.raises(SignalError, match="fewer than 1 distinct"):
        nearest_outside_window(y, 40, min_dist=0.0)
    with pytest.raises(SignalError, match="fewer than 1 distinct"):
        nearest_valid(y, 40, np.inf, 0.0)
    with pytest.raises(SignalError, match="fewer than 1 distinct"):
        nearest_valid(np.c_[y, y], 40, np.inf, 0.0)
