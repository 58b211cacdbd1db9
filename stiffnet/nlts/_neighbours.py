"""Nearest neighbours outside a Theiler window, by batched cKDTree queries."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from stiffnet.errors import SignalError


def nearest_outside_window(
    y: np.ndarray,
    theiler: int,
    p: float = 2.0,
    k: int = 1,
    tree: cKDTree | None = None,
    queries: np.ndarray | None = None,
    query_index: np.ndarray | None = None,
    min_dist: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """The `k` nearest neighbours of each point, excluding temporal neighbours and duplicates.

    A neighbour j of point i is valid if ``|i - j| > theiler`` and its distance
    is > `min_dist` (a duplicate point would make distance ratios infinite; nolitsa
    uses 0, a rounding-error scale also rejects the near-duplicates of exactly
    periodic signals).

    Parameters
    ----------
    y : numpy.ndarray
        Points indexed by time, shape (n, dim); the tree is built on them.
    theiler : int
        Theiler window: neighbours closer in time than this are excluded.
    p : float
        Minkowski norm: 2 (Euclidean) or ``np.inf`` (Chebyshev / maximum norm).
    k : int
        Number of valid neighbours per point.
    tree : cKDTree, optional
        Prebuilt tree on `y`.
    queries, query_index : numpy.ndarray, optional
        Query other points instead of `y` itself, with their time indices in
        `y`'s time axis for the Theiler exclusion; without `query_index` the
        queries are unrelated in time to `y` and nothing is excluded by time.
    min_dist : float
        Distances <= this count as duplicates.

    Returns
    -------
    dist, idx : numpy.ndarray
        Shape (n_queries, k): distances (ascending) and indices into `y`.

    Notes
    -----
    A first query asks for only ``k + 1`` neighbours: for delay vectors with a
    sensible delay the nearest points are mostly on other orbit passes, so this
    settles most rows at a fraction of the cost of a large `k`. Rows left over
    are queried again with twice as many neighbours, capped at
    ``k + 2 * theiler + 1`` - at most ``2 * theiler + 1`` of those lie inside
    the window (the point itself included), so that round finds `k` valid ones
    unless there are duplicates, which only further doubling resolves. The
    first `k` valid entries of a distance-sorted list are the `k` nearest valid
    neighbours, so the staged search is exact.
    """
    n = y.shape[0]
    if tree is None:
        tree = cKDTree(y)
    if queries is None:
        queries, query_index = y, np.arange(n)
    elif query_index is None:
        theiler = 0
        query_index = np.full(queries.shape[0], -1, dtype=np.intp)  # |i - j| > 0 for all j
    m = queries.shape[0]
    dist = np.empty((m, k))
    idx = np.empty((m, k), dtype=np.intp)
    todo = np.arange(m)
    kq = min(k + 1, k + 2 * theiler + 1)
    while todo.size:
        kq = min(kq, n)
        q = queries if todo.size == m else queries[todo]
        d, i = tree.query(q, k=kq, p=p)
        d, i = d.reshape(todo.size, kq), i.reshape(todo.size, kq)
        valid = (np.abs(i - query_index[todo, None]) > theiler) & (d > min_dist)
        rank = np.cumsum(valid, axis=1)
        ok = rank[:, -1] >= k
        take = valid & (rank <= k) & ok[:, None]
        dist[todo[ok]] = d[take].reshape(-1, k)
        idx[todo[ok]] = i[take].reshape(-1, k)
        todo = todo[~ok]
        if todo.size and kq == n:
            raise SignalError(
                f"{todo.size} points have fewer than {k} distinct neighbours outside the "
                f"Theiler window {theiler}; signal too short or too repetitive"
            )
        # Double until the guaranteed size, then keep doubling (duplicates only).
        guaranteed = k + 2 * theiler + 1
        kq = 2 * kq if kq >= guaranteed else min(2 * kq, guaranteed)
    return dist, idx
