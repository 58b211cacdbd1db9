"""Embedding dimension: false nearest neighbours and Cao's method (paper section 4.1.2, eq. 3).

Both methods compare each delay vector's nearest neighbour in dimension m with
the same pair in dimension m + 1. Neighbours exclude the point itself, its
temporal neighbours (Theiler window) and duplicates (rounding-error distance).
They are found by sorting in dimension 1 and by batched
:class:`scipy.spatial.cKDTree` queries above; for Cao's maximum norm a neighbour
certified unique in dimension m is carried into m + 1 without a search where
it provably stays the nearest (see :func:`_pairs`). The results are those of
one plain tree search per dimension, bit for bit.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import ArrayLike

from stiffnet.errors import SignalError
from stiffnet.nlts._neighbours import nearest_outside_window, nearest_valid
from stiffnet.nlts._validate import as_signal, check_choice, check_curve, check_int
from stiffnet.nlts.delay import Estimate
from stiffnet.nlts.embedding import embed_unchecked

_NORMS = {"chebyshev": np.inf, "euclidean": 2.0}


def _prepare(
    x: ArrayLike, tau: int, max_dim: int, theiler: int | None, top: int
) -> tuple[np.ndarray, int, int, int]:
    tau = check_int(tau, "tau", 1)
    max_dim = check_int(max_dim, "max_dim", 1)
    theiler = tau if theiler is None else check_int(theiler, "theiler", 0)
    a = as_signal(x, 2)
    # The largest embedding needs `top` coordinates and still enough points to
    # find neighbours outside the Theiler window.
    need = (top - 1) * tau + 2 * theiler + 10
    if a.size < need:
        raise SignalError(
            f"signal is too short for max_dim={max_dim}, tau={tau}, theiler={theiler}: "
            f"{a.size} samples, at least {need} needed"
        )
    return a, tau, max_dim, theiler


def _pairs(
    a: np.ndarray, top: int, tau: int, theiler: int, p: float
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Nearest neighbour distance in dimension m and the (m+1)-th coordinate gap, m = 1..top.

    Uses the N - m*tau vectors whose (m+1)-th coordinate exists, as nolitsa does.

    For the maximum norm a neighbour found in dimension m is often still the
    nearest in m + 1, and provably so without a search: its distance there is
    ``max(R_m, gap)`` (known), and every other valid point is at least as far as
    in dimension m, where :func:`nearest_valid` certified them all beyond a bound.
    If the new distance is below that bound, the neighbour carries over (with its
    bound); only the other points are searched. The result is the search's, bit
    for bit: the maximum of the same numbers, and a unique nearest neighbour.

    Dimension 1 is searched by sorting. The Euclidean norm carries nothing over
    (the tree's distances are not recomputed bit for bit here), so from
    dimension 2 on it uses the plain staged search, which asks for 2 neighbours,
    not 3. So does the maximum norm once more than a quarter of a dimension's
    searched rows needed the plain search anyway (distance ties and duplicates:
    quantised signals), not to search them twice.
    """
    # Pairs closer than rounding error are duplicates (exactly periodic signals).
    tiny = 1e-10 * float(np.ptp(a))
    carried = None  # (distance in dimension m, neighbour, bound) for the next m
    for m in range(1, top + 1):
        n = a.size - m * tau
        y = embed_unchecked(a[: n + (m - 1) * tau], m, tau)
        fast = False
        if carried is not None:
            # Carried neighbours must exist in dimension m (index < n).
            dist, idx, bound = (v[:n] for v in carried)
            rows = np.flatnonzero((dist >= bound) | (idx >= n))
            fast = True
            if rows.size:
                dist[rows], idx[rows], bound[rows], plain = nearest_valid(y, theiler, p, tiny, rows)
                fast = plain.mean() <= 0.25
        elif m == 1:
            # Duplicates in one dimension (a quantised signal) are common and
            # say little about dimension 2: that one decides.
            dist, idx, bound, _ = nearest_valid(y, theiler, p, tiny)
            fast = True
        else:
            d, i = nearest_outside_window(y, theiler, p=p, min_dist=tiny)
            dist, idx = d[:, 0], i[:, 0]
        nxt = a[m * tau :]  # nxt[i] = x_{i + m tau}, the coordinate added in dimension m + 1
        extra = np.abs(nxt - nxt[idx])
        yield dist, extra
        carried = (np.maximum(dist, extra), idx, bound) if fast and p == np.inf else None


def false_nearest_neighbours(
    x: ArrayLike,
    tau: int,
    max_dim: int = 10,
    rtol: float = 15.0,
    atol: float = 2.0,
    theiler: int | None = None,
    norm: str = "euclidean",
) -> np.ndarray:
    """Fraction of false nearest neighbours for m = 1..max_dim (Kennel et al. 1992).

    ``norm="euclidean"`` (default, Kennel et al. 1992 as in nolitsa): for each
    delay vector y_i(m) of the N - m tau whose (m+1)-th coordinate exists, with
    nearest neighbour y_j(m) at Euclidean distance R_m, the neighbour is false if

    * test I: ``|x_{i+m tau} - x_{j+m tau}| / R_m > rtol`` (the pair separates
      when the (m+1)-th coordinate is added; the paper's threshold R_tr), or
    * test II: ``R_{m+1} / R_A > atol`` with R_A the standard deviation of the
      signal (the neighbour was not close to begin with);

    the fraction is over all those vectors.

    ``norm="max"`` is TISEAN's ``false_nearest`` definition (Hegger et al. 1999):
    maximum-norm distance R_m; test I with ``rtol`` as TISEAN's ``-f`` (its
    default is 2, not 15); no test II - instead only pairs with
    ``R_m <= sigma / rtol`` are counted (sigma the standard deviation), and the
    fraction is over the counted pairs. As in TISEAN the reference points are
    i < N - max_dim tau and the candidate neighbours j < N - (max_dim + 1) tau
    for every m, neighbours at distance 0 are skipped, and TISEAN's Theiler window
    defaults to 0 (``-t``): ``false_nearest_neighbours(x, tau, M, rtol=2.0,
    theiler=0, norm="max")`` gives TISEAN's ``false_nearest -d tau -M M``
    fractions (``tests/test_nlts_dimension.py`` checks this against a brute-force
    implementation of that definition). On impact data the two definitions differ
    by up to 0.03 in the fractions, and can pick a dimension one apart.

    Parameters
    ----------
    x : array_like
        Scalar time series.
    tau : int
        Embedding delay in samples.
    max_dim : int, optional
        Largest dimension m examined.
    rtol, atol : float, optional
        Kennel's thresholds (rtol 10-15, atol 2).
    theiler : int, optional
        Neighbours closer than this many samples in time are excluded; default `tau`.
    norm : {"euclidean", "max"}
        The definition (see above): Kennel's with the Euclidean norm, or TISEAN's.

    Returns
    -------
    numpy.ndarray
        ``fractions[m - 1]`` is the FNN fraction in dimension m, shape ``(max_dim,)``;
        NaN where ``norm="max"`` counts no pair (TISEAN: "Not enough points").
    """
    norm = check_choice(norm, "norm", ("euclidean", "max"))
    a, tau, max_dim, theiler = _prepare(x, tau, max_dim, theiler, max_dim + 1)
    if norm == "max":
        return _fnn_tisean(a, tau, max_dim, rtol, theiler)
    r_a = a.std()
    out = np.empty(max_dim)
    for m, (dist, extra) in enumerate(_pairs(a, max_dim, tau, theiler, 2.0), start=1):
        false = (extra > rtol * dist) | (np.hypot(dist, extra) > atol * r_a)
        out[m - 1] = false.mean()
    return out


def _fnn_tisean(a: np.ndarray, tau: int, max_dim: int, rtol: float, theiler: int) -> np.ndarray:
    """TISEAN ``false_nearest`` fractions (see :func:`false_nearest_neighbours`)."""
    n_ref = a.size - max_dim * tau
    n_cand = a.size - (max_dim + 1) * tau
    cut = a.std() / rtol
    out = np.full(max_dim, np.nan)
    for m in range(1, max_dim + 1):
        cand = embed_unchecked(a[: n_cand + (m - 1) * tau], m, tau)
        ref = embed_unchecked(a[: n_ref + (m - 1) * tau], m, tau)
        dist, idx = nearest_outside_window(cand, theiler, p=np.inf, queries=ref,
                                           query_index=np.arange(n_ref), min_dist=0.0)  # fmt: skip
        dist, idx = dist[:, 0], idx[:, 0]
        counted = dist <= cut
        if counted.any():
            gap = np.abs(a[np.arange(n_ref) + m * tau] - a[idx + m * tau])
            out[m - 1] = np.mean(gap[counted] > rtol * dist[counted])
    return out


def cao_curves(
    x: ArrayLike,
    tau: int,
    max_dim: int = 10,
    theiler: int | None = None,
    metric: str = "chebyshev",
) -> tuple[np.ndarray, np.ndarray]:
    """Cao's E1(d) and E2(d) for d = 1..max_dim (Cao 1997; eq. 3 of the paper).

    With y_n(i,d) the nearest neighbour of y_i(d) (eq. 3),

    ``a(i, d) = ||y_i(d+1) - y_n(i,d)(d+1)|| / ||y_i(d) - y_n(i,d)(d)||``,
    ``E(d) = mean_i a(i, d)``, ``E1(d) = E(d+1) / E(d)``,
    ``E*(d) = mean_i |x_{i+d tau} - x_{n(i,d)+d tau}|``, ``E2(d) = E*(d+1) / E*(d)``.

    Parameters
    ----------
    x : array_like
        Scalar time series.
    tau : int
        Embedding delay in samples.
    max_dim : int, optional
        Largest d; E(d) is computed up to ``max_dim + 1``.
    theiler : int, optional
        Temporal exclusion window for neighbours; default `tau`.
    metric : {"chebyshev", "euclidean"}
        Norm. Cao (1997) and nolitsa use the maximum (Chebyshev) norm, for which
        adding a coordinate never shrinks a distance, so ``a(i, d) >= 1``; the
        paper writes eq. 3 with the Euclidean norm.

    Returns
    -------
    E1, E2 : numpy.ndarray
        Shape ``(max_dim,)``; index ``d - 1`` holds E1(d), E2(d). E1 saturates
        (near 1) from the minimum embedding dimension on for deterministic
        data; E2 is about 1 for every d for random data, not for deterministic.
    """
    check_choice(metric, "metric", tuple(_NORMS))
    p = _NORMS[metric]
    a, tau, max_dim, theiler = _prepare(x, tau, max_dim, theiler, max_dim + 2)
    e = np.empty(max_dim + 1)
    es = np.empty(max_dim + 1)
    for d, (dist, extra) in enumerate(_pairs(a, max_dim + 1, tau, theiler, p), start=1):
        grown = np.maximum(dist, extra) if p == np.inf else np.hypot(dist, extra)
        e[d - 1] = np.mean(grown / dist)
        es[d - 1] = np.mean(extra)
    if es[:-1].min() == 0:
        raise SignalError("E*(d) is zero: the signal is exactly predictable from its neighbours")
    return e[1:] / e[:-1], es[1:] / es[:-1]


def fnn_dimension(fractions: ArrayLike, threshold: float = 0.01) -> int:
    """Rule: smallest m whose false-nearest-neighbour fraction is <= `threshold`.

    Parameters
    ----------
    fractions : array_like
        Output of :func:`false_nearest_neighbours` (index m - 1).
    threshold : float, optional
        Acceptable fraction of false neighbours (Kennel's "drops to zero").
        Noise keeps the fraction above zero: raise it (e.g. 0.05) for noisy data.

    Returns
    -------
    int
        The embedding dimension m (1-based).

    Raises
    ------
    SignalError
        If the fraction never falls to `threshold`.
    """
    f = check_curve(fractions, "fractions", 1)
    ok = np.flatnonzero(f <= threshold)
    if ok.size == 0:
        m = int(np.argmin(f)) + 1
        raise SignalError(
            f"FNN fraction never falls to {threshold:g} (lowest {f.min():.3g} at m={m}); "
            "noisy signal? raise the threshold or max_dim"
        )
    return int(ok[0] + 1)


def cao_dimension(e1: ArrayLike, tol: float = 0.1) -> int:
    """Rule: smallest d whose E1(d) is within `tol` (relative) of the E1 plateau.

    Cao (1997): E1(d) stops changing once d is large enough; the minimum
    embedding dimension is the first d on the plateau. The plateau level is
    taken as ``max(E1)`` (near 1 for deterministic data; for finite data it may
    sit a little below 1), and the rule returns the first d with
    ``E1(d) >= (1 - tol) * max(E1)``. neurokit2 uses the same rule with
    ``tol = 0.15``.

    Parameters
    ----------
    e1 : array_like
        E1 from :func:`cao_curves` (index d - 1).
    tol : float, optional
        Relative tolerance to the plateau.

    Returns
    -------
    int
        The embedding dimension (1-based).
    """
    e = check_curve(e1, "E1", 1)
    return int(np.flatnonzero(e >= (1.0 - tol) * e.max())[0] + 1)


def estimate_dimension(
    x: ArrayLike,
    tau: int,
    max_dim: int = 10,
    method: str = "cao",
    theiler: int | None = None,
    **rule_kwargs: float,
) -> Estimate:
    """Estimate the embedding dimension (section 4.1.2).

    Parameters
    ----------
    x : array_like
        Scalar time series.
    tau : int
        Embedding delay, e.g. from :func:`stiffnet.nlts.estimate_delay`.
    max_dim : int, optional
        Largest dimension examined.
    method : {"cao", "fnn"}
        :func:`cao_curves` + :func:`cao_dimension`, or
        :func:`false_nearest_neighbours` + :func:`fnn_dimension`.
    theiler : int, optional
        Temporal exclusion window; default `tau`.
    **rule_kwargs
        Passed to the rule (`tol` for Cao, `threshold` for FNN).

    Returns
    -------
    Estimate
        ``(value, rule)``: the dimension and the name of the rule used.
    """
    check_choice(method, "dimension method", ("cao", "fnn"))
    if method == "cao":
        e1, _ = cao_curves(x, tau, max_dim, theiler)
        return Estimate(cao_dimension(e1, **rule_kwargs), "cao_dimension")
    f = false_nearest_neighbours(x, tau, max_dim, theiler=theiler)
    return Estimate(fnn_dimension(f, **rule_kwargs), "fnn_dimension")
