"""Stationarity: cross-prediction errors between segments (paper section 4.2.1).

Schreiber's (1997) idea, also behind TISEAN ``nstat_z``: the record is cut into
non-overlapping segments, each segment's delay vectors serve as the "model" that
predicts every other segment with a locally constant (nearest-neighbour average)
predictor. If the dynamics changed during the record, segments from different
regimes predict each other badly.

Not TISEAN's numbers by default: stiffnet averages the `k` nearest neighbours in
the Euclidean norm and divides the RMS error by the whole signal's standard
deviation; ``nstat_z`` averages an epsilon-neighbourhood in the maximum norm
(grown by a factor until it holds at least ``-k`` points) and divides by the
standard deviation of the segment forecast. ``norm="max", scale="segment"``
reproduces the norm and the normalisation; the neighbourhood (k nearest versus
an epsilon-ball of at least k points) remains different.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from stiffnet.errors import ConfigError
from stiffnet.nlts._neighbours import nearest_outside_window
from stiffnet.nlts._validate import as_signal, check_choice, check_int
from stiffnet.nlts.embedding import embed_unchecked


def cross_prediction_errors(
    x: ArrayLike,
    dim: int,
    tau: int,
    n_segments: int = 4,
    horizon: int = 1,
    n_neighbours: int = 5,
    theiler: int | None = None,
    norm: str = "euclidean",
    scale: str = "signal",
) -> np.ndarray:
    """Matrix of cross-prediction errors ``S[i, j]``: segment i predicting segment j.

    For every delay vector y_t (dimension `dim`, delay `tau`) of segment j, the
    `n_neighbours` nearest delay vectors of segment i are found (cKDTree, in the
    `norm`), and the future value ``x_{t + (dim-1) tau + horizon}`` is
    predicted as the mean of their futures (locally constant predictor).
    ``S[i, j] = sqrt(mean_t (prediction - x)^2) / sigma``, with sigma the standard
    deviation of the whole signal (``scale="signal"``) or of segment j
    (``scale="segment"``, TISEAN ``nstat_z``'s normalisation).

    Parameters
    ----------
    x : array_like
        Scalar time series; the last ``len(x) % n_segments`` samples are dropped.
    dim, tau : int
        Embedding dimension and delay.
    n_segments : int, optional
        Number of non-overlapping, equal-length segments (>= 2).
    horizon : int, optional
        Prediction horizon in samples.
    n_neighbours : int, optional
        Neighbours averaged by the predictor. TISEAN ``nstat_z`` uses an
        epsilon-neighbourhood grown by a factor until enough neighbours are
        found; a fixed number of neighbours is the same idea with an adaptive
        radius, and is one batched KD-tree query.
    theiler : int, optional
        For the diagonal (a segment predicting itself) neighbours closer than
        this in time are excluded, so a point never predicts itself. Default
        ``(dim - 1) * tau + horizon``: the neighbour shares no sample with the
        point's delay vector or its target.
    norm : {"euclidean", "max"}
        Distance between delay vectors; TISEAN uses the maximum norm.
    scale : {"signal", "segment"}
        Divide by the standard deviation of the whole signal, or of the
        predicted segment (as ``nstat_z`` does).

    Returns
    -------
    numpy.ndarray
        Shape ``(n_segments, n_segments)``; ``S[i, j]`` is the root-mean-square
        prediction error of segment j from segment i divided by sigma (1 = no
        better than predicting the mean; the paper's Fig. 5 has values 0.11-0.19).
    """
    p = {"euclidean": 2.0, "max": np.inf}[check_choice(norm, "norm", ("euclidean", "max"))]
    scale = check_choice(scale, "scale", ("signal", "segment"))
    dim = check_int(dim, "dim", 1)
    tau = check_int(tau, "tau", 1)
    n_segments = check_int(n_segments, "n_segments", 2)
    horizon = check_int(horizon, "horizon", 1)
    k = check_int(n_neighbours, "n_neighbours", 1)
    span = (dim - 1) * tau
    theiler = span + horizon if theiler is None else check_int(theiler, "theiler", 0)
    # Each segment needs k neighbours outside the window plus some slack.
    seg_len_min = span + horizon + 2 * theiler + k + 10
    a = as_signal(x, n_segments * seg_len_min, "signal")
    length = a.size // n_segments
    sigma = a.std()

    vectors, futures = [], []
    for s in range(n_segments):
        seg = a[s * length : (s + 1) * length]
        vectors.append(embed_unchecked(seg[: length - horizon], dim, tau))
        futures.append(seg[span + horizon :])

    out = np.empty((n_segments, n_segments))
    for i in range(n_segments):
        tree = cKDTree(vectors[i])
        for j in range(n_segments):
            if i == j:
                _, idx = nearest_outside_window(
                    vectors[i], theiler, p=p, k=k, tree=tree, min_dist=-1.0
                )
            else:
                _, idx = tree.query(vectors[j], k=k, p=p)
                idx = idx.reshape(-1, k)
            pred = futures[i][idx].mean(axis=1)
            seg = a[j * length : (j + 1) * length]
            ref = seg.std() if scale == "segment" else sigma
            out[i, j] = np.sqrt(np.mean((pred - futures[j]) ** 2)) / ref
    return out


def is_stationary(errors: ArrayLike, factor: float = 2.0, floor: float = 0.02) -> bool:
    """Rule: stationary if no cross-prediction error exceeds `factor` times the smallest.

    The paper (section 4.2.1, Fig. 5) calls the data stationary because the
    largest error (0.187) is "not even one time larger" than the smallest
    (0.106): every segment predicts every other about as well as the best pair
    does. A segment recorded under different dynamics is predicted badly by
    the others (and predicts them badly), so its row and column stand out.
    The rule is ``max(S) <= factor * max(min(S), floor)``.

    Parameters
    ----------
    errors : array_like
        Square matrix from :func:`cross_prediction_errors`.
    factor : float, optional
        Allowed ratio between the largest and the smallest error (the paper's
        "one time larger" is 2).
    floor : float, optional
        Lower bound for the reference error (in units of the signal's standard
        deviation). Noise-free data can be predicted almost perfectly, and a
        ratio of two tiny errors says nothing; errors below 2% of the signal's
        spread count as equally good.

    Returns
    -------
    bool
        True if the record looks stationary.
    """
    s = np.asarray(errors, dtype=np.float64)
    if s.ndim != 2 or s.shape[0] != s.shape[1] or s.shape[0] < 2:
        raise ConfigError(f"errors must be a square matrix of size >= 2, got shape {s.shape}")
    if not factor >= 1:
        raise ConfigError(f"factor must be >= 1, got {factor}")
    return bool(s.max() <= factor * max(float(s.min()), floor))


def record_probes(
    x: ArrayLike, n_segments: int, max_samples: int
) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Equal probes spread over the whole record, for a bounded whole-record test.

    A record longer than `max_samples` is not cut at `max_samples` (which tests only
    its beginning and misses a change of dynamics later on): it is cut into
    `n_segments` equal parts and the middle ``max_samples // n_segments`` samples of
    each are kept. Concatenated, the probes are the segments of
    :func:`cross_prediction_errors` (``n_segments`` of them), so every part of the
    record predicts every other.

    Returns
    -------
    (numpy.ndarray, list of (int, int))
        The concatenated probes and each probe's ``[start, stop)`` in the record.
    """
    a = np.asarray(x, dtype=np.float64)
    n_segments = check_int(n_segments, "n_segments", 2)
    if a.size <= max_samples:
        length = a.size // n_segments
        return a[: length * n_segments], [(k * length, (k + 1) * length) for k in
                                           range(n_segments)]  # fmt: skip
    part = a.size // n_segments
    length = min(part, max_samples // n_segments)
    spans = []
    for k in range(n_segments):
        start = k * part + (part - length) // 2
        spans.append((start, start + length))
    return np.concatenate([a[lo:hi] for lo, hi in spans]), spans
