"""Delay-coordinate embedding (paper section 4.1, eq. 1)."""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import ArrayLike

from stiffnet.errors import SignalError
from stiffnet.nlts._validate import as_signal, check_int


def delay_embed(x: ArrayLike, dim: int, tau: int) -> np.ndarray:
    """Delay vectors ``y_i = (x_i, x_{i+tau}, ..., x_{i+(dim-1)tau})`` (eq. 1).

    Parameters
    ----------
    x : array_like
        Scalar time series of length N.
    dim : int
        Embedding dimension m >= 1.
    tau : int
        Embedding delay in samples, >= 1.

    Returns
    -------
    numpy.ndarray
        C-contiguous array of shape ``(N - (dim - 1) * tau, dim)``; row i is y_i.

    Raises
    ------
    ConfigError
        If `dim` or `tau` is not a positive integer.
    SignalError
        If the signal is invalid or too short to give at least two vectors.
    """
    dim = check_int(dim, "dim", 1)
    tau = check_int(tau, "tau", 1)
    a = as_signal(x, 2)
    need = (dim - 1) * tau + 2
    if a.size < need:
        raise SignalError(
            f"signal is too short to embed with dim={dim}, tau={tau}: "
            f"{a.size} samples, at least {need} needed"
        )
    return embed_unchecked(a, dim, tau)


def embed_unchecked(a: np.ndarray, dim: int, tau: int) -> np.ndarray:
    """:func:`delay_embed` for an already validated float array (internal fast path)."""
    span = (dim - 1) * tau
    # Windows of span+1 samples, keep every tau-th: a strided view, then one copy
    # so callers (and cKDTree) get ordinary contiguous memory.
    return np.ascontiguousarray(sliding_window_view(a, span + 1)[:, ::tau])
