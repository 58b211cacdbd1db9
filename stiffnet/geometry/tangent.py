"""Tangent vectors of the embedded trajectory (paper section 5.1, eqs 4-6).

The paper computes, for each coordinate of the reconstructed phase space, the
difference between two points ``n`` samples apart,

``V_x(N - n) = x(N) - x(N - n)``, ``V_y(N - n) = y(N) - y(N - n)``,
``V_z(N - n) = z(N) - z(N - n)``  (eqs 4-6),

and uses the magnitude of ``V = (V_x, V_y, V_z)`` to tell contact from
free-flight points (contact points move much faster) and its direction in the
x-z projection to measure inclinations (eqs 7-10). ``n`` "is determined by the
sampling rate and the amount of averaging required": :func:`tangent_lag` is
the rule used here.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from stiffnet.errors import ConfigError, SignalError
from stiffnet.nlts._validate import check_int

#: Default tangent lag as a fraction of the dominant (forcing) period: one
#: sample at the paper's sampling (about 95 samples per forcing period).
TANGENT_LAG_FRACTION = 0.01


def _as_trajectory(y: ArrayLike, min_dim: int = 1) -> np.ndarray:
    pts = np.asarray(y, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] < min_dim:
        raise SignalError(
            f"trajectory must have shape (N, dim >= {min_dim}), got an array of shape {pts.shape}"
        )
    if not np.isfinite(pts).all():
        raise SignalError("trajectory contains NaN or inf values")
    return pts


def tangent_vectors(y: ArrayLike, lag: int = 1) -> np.ndarray:
    """Tangent vectors ``V_i = Y_{i+lag} - Y_i`` of an embedded trajectory (eqs 4-6).

    Parameters
    ----------
    y : array_like
        Embedded trajectory, shape (N, m), rows in time order (e.g. from
        :func:`stiffnet.nlts.delay_embed`).
    lag : int, optional
        The paper's ``n``: samples between the two points of a difference.

    Returns
    -------
    numpy.ndarray
        Shape ``(N - lag, m)``. Row i is the paper's ``V(N - n)`` with
        ``N - n = i``: it belongs to the segment from point i to point
        ``i + lag``, so masks on tangents index the start point of that segment.

    Notes
    -----
    For a delay embedding every coordinate is a shifted copy of the scalar
    increment ``d_i = s_{i+lag} - s_i``: ``V_i = (d_i, d_{i+tau}, d_{i+2 tau}, ...)``.
    """
    pts = _as_trajectory(y)
    lag = check_int(lag, "lag", 1)
    if pts.shape[0] <= lag:
        raise SignalError(f"trajectory of {pts.shape[0]} points is too short for tangent lag {lag}")
    return pts[lag:] - pts[:-lag]


def tangent_magnitudes(v: ArrayLike, coords: tuple[int, ...] = (0, 1, 2)) -> np.ndarray:
    """Euclidean length of the tangent vectors over the coordinates `coords`.

    Parameters
    ----------
    v : array_like
        Tangent vectors, shape (N, m), from :func:`tangent_vectors`.
    coords : tuple of int, optional
        Coordinates that enter the resultant. The paper's ``V_t = (V_x, V_y, V_z)``
        uses the first three delay coordinates (default), whatever the embedding
        dimension.

    Returns
    -------
    numpy.ndarray
        Shape (N,), non-negative.
    """
    vv = _as_trajectory(v, max(coords) + 1)
    return np.sqrt(np.sum(vv[:, list(coords)] ** 2, axis=1))


def tangent_lag(period: float, fraction: float = TANGENT_LAG_FRACTION) -> int:
    """Rule: tangent lag ``n`` as a fixed fraction of the dominant period, at least 1.

    Parameters
    ----------
    period : float
        Dominant (forcing) period of the signal in samples.
    fraction : float, optional
        ``n / period``. The default 0.01 gives ``n = 1`` at the paper's sampling
        (about 95 samples per forcing period) and scales ``n`` with the sampling
        rate, so that the tangents average over the same fraction of an orbit
        whatever the rate (the paper: ``n`` "determined by the sampling rate and
        the amount of averaging required").

    Returns
    -------
    int
        ``max(1, round(fraction * period))``.
    """
    if not period > 0 or not np.isfinite(period):
        raise ConfigError(f"period must be a positive number of samples, got {period}")
    if not 0 < fraction < 1:
        raise ConfigError(f"fraction must be in (0, 1), got {fraction}")
    return max(1, int(round(fraction * period)))
