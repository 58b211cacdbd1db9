"""Smoothing and impact detection on the raw acceleration (paper sections 2, 3 and 5.1).

The paper smooths every time history with a 2nd-order Savitzky-Golay filter,
which keeps the height and sharpness of the impact spikes while removing
noise, and detects impacts either from the derivative of the acceleration or
from the squared deviation from the mean (its "root mean square" rule).
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import ArrayLike
from scipy.ndimage import convolve1d
from scipy.signal import find_peaks, savgol_coeffs

from stiffnet.errors import ConfigError
from stiffnet.nlts._validate import as_signal, check_choice, check_int
from stiffnet.recordings.base import check_rate

# 1.4826 * MAD estimates the standard deviation of Gaussian data.
MAD_TO_SIGMA = 1.4826


def savgol_smooth(x: ArrayLike, window: int, polyorder: int = 2) -> np.ndarray:
    """Savitzky-Golay smoothing, 2nd order by default as in the paper (sections 2 and 5.1).

    Parameters
    ----------
    x : array_like
        Acceleration time history.
    window : int
        Odd window length in samples, larger than `polyorder`.
    polyorder : int, optional
        Order of the local polynomial (the paper uses 2).

    Returns
    -------
    numpy.ndarray
        Smoothed signal, same length. Edges use a polynomial fit to the first
        and last windows (``mode="interp"``) so an impact near an end keeps its
        height.
    """
    polyorder = check_int(polyorder, "polyorder", 0)
    window = check_int(window, "window", polyorder + 1)
    if window % 2 == 0:
        raise ConfigError(f"window must be odd, got {window}")
    a = as_signal(x, window)
    centre, first, last = _savgol_operators(window, polyorder)
    # scipy.signal.savgol_filter(a, window, polyorder, mode="interp") to rounding: the same
    # convolution, and the edges' polynomials applied as the least-squares operators kept
    # per window (scipy fits both edges with polyfit at every call: two thirds of its time)
    y = convolve1d(a, centre, mode="constant")
    half = window // 2
    y[:half] = first @ a[:window]
    y[a.size - half :] = last @ a[a.size - window :]
    return y


@functools.lru_cache(maxsize=64)
def _savgol_operators(window: int, polyorder: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Savitzky-Golay coefficients of the window's centre (as ``convolve1d`` takes them) and
    the ``window // 2`` rows that evaluate the first and the last window's least-squares
    polynomial at its first and last ``window // 2`` samples (read-only).

    The edge rows are the least-squares projection built on the window's samples centred
    and scaled to [-1, 1] (well conditioned: on raw sample numbers the cubic's projection
    of a 101-sample window loses five digits)."""
    half = window // 2
    centre = savgol_coeffs(window, polyorder)
    t = np.linspace(-1.0, 1.0, window)
    basis = np.vander(t, polyorder + 1, increasing=True)
    project = basis @ np.linalg.pinv(basis)  # fitted values of the window from its samples
    first, last = project[:half].copy(), project[window - half :].copy()
    for m in (centre, first, last):
        m.setflags(write=False)
    return centre, first, last


def impact_indicator_derivative(x: ArrayLike, fs: float | None = None) -> np.ndarray:
    """Magnitude of the derivative of the acceleration, ``|da/dt|`` (section 3).

    Impacts are the sharp spikes of the acceleration; differentiating turns the
    slow forced response into a small background and the spikes into large
    peaks, so even near-grazing contacts stand out (paper Fig. 3c).

    Parameters
    ----------
    x : array_like
        Acceleration time history (smooth it first: differentiating amplifies noise).
    fs : float, optional
        Sampling rate in Hz. If given the derivative is per second, else per sample.

    Returns
    -------
    numpy.ndarray
        Non-negative indicator, same length as `x` (central differences).

    Notes
    -----
    The derivative is largest on the flanks of a spike, so the indicator peaks
    up to the spike half-width before or after the acceleration maximum.
    """
    if fs is not None:
        fs = check_rate(fs, "fs", ConfigError)
    a = as_signal(x, 3)
    d = np.abs(np.gradient(a))
    return d * fs if fs is not None else d


def impact_indicator_rms(x: ArrayLike) -> np.ndarray:
    """Squared deviation from the mean, ``(x - mean(x))**2`` (section 3).

    The paper's "root mean square" rule: subtract the mean of all samples from
    each sample and square it; impact samples have far larger values than the
    forced response.

    Parameters
    ----------
    x : array_like
        Acceleration time history.

    Returns
    -------
    numpy.ndarray
        Non-negative indicator, same length as `x`.
    """
    a = as_signal(x, 3)
    return (a - a.mean()) ** 2


def robust_threshold(indicator: ArrayLike, k: float = 8.0) -> float:
    """Automatic impact threshold ``median + k * 1.4826 * MAD`` of the indicator.

    Median and MAD (median absolute deviation) describe the non-impact bulk of
    the signal and are barely moved by the few impact samples, unlike mean and
    standard deviation. For a pure sine the maximum of either indicator is
    less than one scaled MAD above the median, so the default ``k = 8`` leaves
    room for noise; impact spikes exceed it by a wide margin. With the rms
    indicator this means a spike must reach about 2.2 times the amplitude of
    the forced response; the derivative indicator also sees smaller but sharp
    spikes (near-grazing contacts), as the paper notes.

    Parameters
    ----------
    indicator : array_like
        Output of :func:`impact_indicator_derivative` or :func:`impact_indicator_rms`.
    k : float, optional
        Number of robust standard deviations above the median.

    Returns
    -------
    float
        Threshold in the indicator's units.
    """
    ind = np.asarray(indicator, dtype=np.float64)
    med = float(np.median(ind))
    mad = float(np.median(np.abs(ind - med)))
    return med + k * MAD_TO_SIGMA * mad


def detect_impacts(
    x: ArrayLike,
    fs: float | None = None,
    method: str = "derivative",
    threshold: float | None = None,
    min_separation: int | None = None,
    k: float = 8.0,
) -> np.ndarray:
    """Sample indices of the impacts in an acceleration record (section 3).

    Parameters
    ----------
    x : array_like
        Acceleration time history, preferably smoothed (:func:`savgol_smooth`).
    fs : float, optional
        Sampling rate in Hz; scales the derivative indicator to per-second units
        and sets the default `min_separation` to 10 ms.
    method : {"derivative", "rms"}
        Indicator: :func:`impact_indicator_derivative` or :func:`impact_indicator_rms`.
    threshold : float, optional
        Indicator level an impact must exceed. Default: :func:`robust_threshold`
        with `k`.
    min_separation : int, optional
        Minimum number of samples between two impacts; within it only the
        largest indicator peak is kept (one contact gives several peaks, e.g.
        both flanks of a spike). Default: 10 ms if `fs` is given, else 10 samples.
    k : float, optional
        Multiplier of the automatic threshold.

    Returns
    -------
    numpy.ndarray
        Sorted int64 indices of the indicator peaks above the threshold; empty
        if there are no impacts.
    """
    check_choice(method, "impact method", ("derivative", "rms"))
    if fs is not None:
        fs = check_rate(fs, "fs", ConfigError)
    if min_separation is None:
        min_separation = max(1, round(0.01 * fs)) if fs is not None else 10
    min_separation = check_int(min_separation, "min_separation", 1)
    if method == "derivative":
        ind = impact_indicator_derivative(x, fs)
    else:
        ind = impact_indicator_rms(x)
    if threshold is None:
        threshold = robust_threshold(ind, k)
    peaks, _ = find_peaks(ind, height=threshold, distance=min_separation)
    return peaks.astype(np.int64)
