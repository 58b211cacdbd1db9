"""Cutting a recording into model windows, and the CNN's input for many windows at once.

Windows. A model window holds ``periods`` natural periods (16 for the shipped
models), i.e. ``round(periods * fs / f_n)`` samples at the recording's own rate
- exactly how the training dataset cut its windows
(``stiffnet.dataset.sampling``: ``round(duration_periods * fs_ratio)``).
Consecutive windows start ``hop`` samples apart (non-overlapping by default);
the tail that does not fill a whole window is not used.

:func:`canonical_tensor` computes the same tensor as
:func:`stiffnet.features.windows.window_tensor` (the training path) for windows
of equal length and rate, but batched: the Butterworth design is done once,
the standardisation, Savitzky-Golay smoothing, zero-phase filtering and linear
interpolation run on a 2-D array, and only the impact detection behind the
polarity rule loops over windows. A test checks it against ``window_tensor``.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np
from scipy.signal import butter, find_peaks, savgol_filter, sosfiltfilt

from stiffnet.errors import SignalError
from stiffnet.features.windows import CUTOFF_FRACTION, default_delays
from stiffnet.geometry.estimate import _polarity, smoothing_window
from stiffnet.nlts.preprocess import _MAD_TO_SIGMA

#: ``k`` of :func:`stiffnet.nlts.preprocess.detect_impacts` (its default).
IMPACT_K = 8.0


def window_length(fs_hz: float, natural_frequency_hz: float, periods: float) -> int:
    """Samples in a window of `periods` natural periods (the dataset's rounding rule)."""
    return max(8, int(round(periods * fs_hz / natural_frequency_hz)))


def window_starts(n_samples: int, length: int, hop: int) -> np.ndarray:
    """Start indices of the whole windows of `length` samples, `hop` apart."""
    if n_samples < length:
        return np.empty(0, dtype=np.int64)
    return np.arange(0, n_samples - length + 1, max(1, hop), dtype=np.int64)


@lru_cache(maxsize=64)
def _antialias(ratio: float) -> np.ndarray:
    # same design as stiffnet.features.windows._resample, computed once per rate
    return butter(8, CUTOFF_FRACTION * 2.0 / ratio, output="sos")


def _polarities(a: np.ndarray, period: float) -> np.ndarray:
    """Row-wise :func:`stiffnet.features.windows.canonical_polarity` of standardised rows."""
    n = a.shape[1]
    win = min(smoothing_window(period), n - (1 - n % 2))
    s = savgol_filter(a, win, 2, mode="interp", axis=1) if win >= 3 else a
    sep = max(1, int(0.25 * period))
    # detect_impacts(s[i], min_separation=sep) row by row, with the indicator
    # (|gradient|) and its robust threshold (median + 8 * 1.4826 * MAD) computed
    # for all rows at once: the same numbers, less Python overhead.
    ind = np.abs(np.gradient(s, axis=1))
    med = np.median(ind, axis=1)
    thr = med + IMPACT_K * _MAD_TO_SIGMA * np.median(np.abs(ind - med[:, None]), axis=1)
    out = np.empty(a.shape[0])
    for i in range(a.shape[0]):
        peaks, _ = find_peaks(ind[i], height=float(thr[i]), distance=sep)
        pol = _polarity(s[i], peaks.astype(np.int64))
        if pol == 0:
            pol = 1 if float(np.mean(a[i] ** 3)) >= 0 else -1
        out[i] = pol
    return out


def canonical_tensor(
    windows: np.ndarray,
    fs_hz: float,
    natural_frequency_hz: float,
    rate: int,
    periods: int,
    delays: Sequence[int] | None = None,
) -> np.ndarray:
    """CNN input of equal-length windows sampled at one rate.

    Parameters
    ----------
    windows : numpy.ndarray
        Shape ``(N, n)``, at least 32 samples each, none constant.
    fs_hz, natural_frequency_hz : float
        Sampling rate and natural frequency in Hz.
    rate, periods : int
        Canonical samples per natural period and natural periods per window.
    delays : sequence of int, optional
        Channel delays in canonical samples (default :func:`default_delays`).

    Returns
    -------
    numpy.ndarray
        float32, shape ``(N, len(delays), rate * periods)``; equal to
        ``window_tensor(list(windows), fs_hz, natural_frequency_hz, rate, periods, delays)``
        up to floating-point rounding.

    Raises
    ------
    SignalError
        If a window is constant.
    """
    a = np.asarray(windows, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] < 32:
        raise SignalError(f"expected windows of at least 32 samples, got shape {a.shape}")
    delays = default_delays(rate) if delays is None else tuple(int(d) for d in delays)
    sd = a.std(axis=1, keepdims=True)
    if np.any(~(sd > 0)):
        raise SignalError("acceleration window is constant")
    a = (a - a.mean(axis=1, keepdims=True)) / sd
    period = float(fs_hz) / float(natural_frequency_hz)
    a = a * _polarities(a, period)[:, None]

    ratio = period / rate
    n_avail = int(np.floor((a.shape[1] - 1) / ratio)) + 1
    if ratio > 1.1:
        a = sosfiltfilt(_antialias(ratio), a, axis=1)
    t = np.arange(n_avail, dtype=np.float64) * ratio
    i0 = np.minimum(np.floor(t).astype(np.int64), a.shape[1] - 1)
    i1 = np.minimum(i0 + 1, a.shape[1] - 1)
    frac = t - i0
    c = a[:, i0] * (1.0 - frac) + a[:, i1] * frac  # np.interp, row-wise
    n = rate * periods
    if c.shape[1] > n:
        start = (c.shape[1] - n) // 2
        c = c[:, start : start + n]
    c = c - c.mean(axis=1, keepdims=True)
    sd = c.std(axis=1, keepdims=True)
    if np.any(~(sd > 0)):
        raise SignalError("acceleration window is constant after resampling")
    w = np.zeros((a.shape[0], n), dtype=np.float32)
    w[:, : c.shape[1]] = c / sd
    out = np.zeros((a.shape[0], len(delays), n), dtype=np.float32)
    for k, d in enumerate(delays):
        if d < n:
            out[:, k, : n - d] = w[:, d:]
    return out
