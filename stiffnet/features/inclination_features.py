"""Tangent-vector inclination features and gain-invariant waveform statistics.

:func:`inclination_features` turns one acceleration window into a fixed-length
float64 vector (names in :data:`FEATURE_NAMES`) for the gradient-boosting
models of ``training/families/gbm/``:

* the paper's **inclination statistics** from
  :func:`stiffnet.geometry.geometric_estimate` (section 5): mean angles before
  and after impact by the gradient and the polynomial approaches, the
  per-orbit spread (standard deviation) of the polynomial angles, the number
  of orbits, the contact fraction and Otsu's separation statistics of the
  tangent magnitudes;
* **tangent-magnitude quantiles** (log10, from the separation's histogram) of
  the standardised, smoothed signal;
* **timing**: impacts per dominant period and, when the natural frequency is
  known, the dominant period in natural periods (``1 / omega`` for a
  period-1 orbit);
* **waveform statistics** of the standardised window: excess kurtosis,
  ``|skewness|``, crest factor ``max |z|``, peak-to-peak range, and the
  impact-spike width at half height in fractions of the dominant period.

Invariances. The window is standardised first (zero mean, unit standard
deviation), so a sensor gain changes nothing. Polarity: the geometric part is
sign-free already (see :mod:`stiffnet.geometry.estimate`); the waveform part
uses ``|skewness|``, ``max |z|`` and the range, which do not change under
``z -> -z``, and the spike width is measured on the window flipped to the
**canonical polarity: impact spikes pointing up** (the geometric method's
detected polarity; the sign of the skewness when it found no contact). Only
floating-point rounding differs between ``a``, ``1000 a`` and ``-a``.

Delay and dimension are *not* features: the delay rule is ``round(0.18 T)``,
a constant fraction of the period, and the dimension is fixed at 3
(:data:`EMBEDDING_DIMENSION`) - the method only uses the first three
coordinates, so Cao's rule would only shorten the embedding by a few delays
while tripling the cost (about 5 ms instead of 14 ms for a window of 8
natural periods at fs = 50-150 f_n).

Fill values (:data:`FILL_VALUES`). Windows without usable contact get
``contact_detected = 0`` and ``-1`` for every angle, spread, spike width and
contact quantity that needs contact (angles lie in [0, 90] and the other
quantities are non-negative, so -1 is outside every genuine value and a tree
splits it off cleanly). If the geometric chain cannot run at all (e.g. the
window holds fewer than three dominant periods) its features are filled the
same way and ``geometry_ok = 0``. An unknown natural frequency gives
``period_natural = -1``. The vector never contains NaN or inf.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from stiffnet.errors import SignalError
from stiffnet.geometry.calibration import GeometricCalibration
from stiffnet.geometry.estimate import GeometricResult, dominant_period, geometric_estimate
from stiffnet.nlts._validate import as_signal

#: Bumped whenever a feature's definition changes (recorded in model metadata).
FEATURE_VERSION = 1
#: Embedding dimension passed to :func:`geometric_estimate` (fixed, see the module notes).
EMBEDDING_DIMENSION = 3
#: Value for features that need contact (or the natural frequency) when there is none.
FILL = -1.0

FEATURE_NAMES: list[str] = [
    "geometry_ok",
    "contact_detected",
    "gradient_before_deg",
    "gradient_after_deg",
    "polynomial_before_deg",
    "polynomial_after_deg",
    "polynomial_before_std_deg",
    "polynomial_after_std_deg",
    "n_orbits_per_period",
    "contact_fraction",
    "separability",
    "log10_mode_ratio",
    "log10_tangent_q50",
    "log10_tangent_q90",
    "log10_tangent_q99",
    "log10_tangent_q99_over_q50",
    "impacts_per_period",
    "period_natural",
    "kurtosis",
    "abs_skewness",
    "crest_factor",
    "peak_to_peak",
    "spike_width_half_height",
]

#: Feature -> value used when it cannot be computed (see the module notes).
FILL_VALUES: dict[str, float] = {
    "geometry_ok": 0.0,
    "contact_detected": 0.0,
    "gradient_before_deg": FILL,
    "gradient_after_deg": FILL,
    "polynomial_before_deg": FILL,
    "polynomial_after_deg": FILL,
    "polynomial_before_std_deg": FILL,
    "polynomial_after_std_deg": FILL,
    "n_orbits_per_period": 0.0,
    "contact_fraction": 0.0,
    "separability": FILL,
    "log10_mode_ratio": FILL,
    "log10_tangent_q50": FILL,
    "log10_tangent_q90": FILL,
    "log10_tangent_q99": FILL,
    "log10_tangent_q99_over_q50": FILL,
    "impacts_per_period": 0.0,
    "period_natural": FILL,
    "kurtosis": FILL,
    "abs_skewness": FILL,
    "crest_factor": FILL,
    "peak_to_peak": FILL,
    "spike_width_half_height": FILL,
}

_INDEX = {name: i for i, name in enumerate(FEATURE_NAMES)}


def _hist_quantiles(counts: np.ndarray, edges: np.ndarray, qs: Sequence[float]) -> np.ndarray:
    """Quantiles of a histogram by linear interpolation of its cumulative counts."""
    cdf = np.concatenate([[0.0], np.cumsum(counts, dtype=np.float64)])
    cdf /= cdf[-1]
    return np.interp(qs, cdf, edges)


def _spike_width(z: np.ndarray, impacts: np.ndarray, period: float) -> float:
    """Median width at half height of the upward spikes at ``impacts``, in periods.

    For each impact, the peak is the maximum of ``z`` within a quarter period;
    its height is measured from the window's median and the width is the run of
    samples around the peak above half of that height.
    """
    if impacts.size == 0:
        return FILL
    half = max(1, int(0.25 * period))
    base = float(np.median(z))
    widths = []
    for i in impacts:
        lo, hi = max(0, int(i) - half), min(z.size, int(i) + half + 1)
        p = lo + int(np.argmax(z[lo:hi]))
        level = base + 0.5 * (z[p] - base)
        if z[p] <= base:
            continue
        below = z[max(0, p - 2 * half) : p] <= level
        left = int(np.argmax(below[::-1])) if below.any() else below.size
        below = z[p + 1 : p + 1 + 2 * half] <= level
        right = int(np.argmax(below)) if below.any() else below.size
        widths.append(left + right + 1)
    return float(np.median(widths)) / period if widths else FILL


def _moments(z: np.ndarray) -> tuple[float, float]:
    """Skewness and excess kurtosis of a standardised signal."""
    return float(np.mean(z**3)), float(np.mean(z**4) - 3.0)


def window_geometry(
    accel: ArrayLike,
    fs_hz: float,
    calibration: GeometricCalibration | str | Path | None = None,
) -> tuple[np.ndarray, GeometricResult | None]:
    """The standardised window and the geometric estimate the features are read from.

    Parameters
    ----------
    accel : array_like
        Acceleration window (any gain, either polarity).
    fs_hz : float
        Sampling rate in Hz.
    calibration : GeometricCalibration, path, "default" or None, optional
        Passed to :func:`geometric_estimate`.

    Returns
    -------
    standardised : numpy.ndarray
        The window with zero mean and unit standard deviation.
    estimate : GeometricResult or None
        :func:`geometric_estimate` in :data:`EMBEDDING_DIMENSION` dimensions; None if it
        raised :class:`SignalError`.

    Raises
    ------
    SignalError
        If the window is not a finite, non-constant 1-D signal of at least 32 samples.
    """
    a = as_signal(accel, 32, "acceleration")
    a = (a - a.mean()) / a.std()
    try:
        est = geometric_estimate(
            a, float(fs_hz), dimension=EMBEDDING_DIMENSION, calibration=calibration
        )
    except SignalError:
        est = None
    return a, est


def features_and_estimate(
    accel: ArrayLike,
    fs_hz: float,
    natural_frequency_hz: float | None = None,
    calibration: GeometricCalibration | str | Path | None = None,
) -> tuple[np.ndarray, GeometricResult | None]:
    """Feature vector of one window and the geometric result it came from.

    Parameters
    ----------
    accel : array_like
        Acceleration window (any gain, either polarity).
    fs_hz : float
        Sampling rate in Hz.
    natural_frequency_hz : float or None, optional
        Natural frequency of the oscillator if known; None (or a non-positive
        or non-finite value) gives ``period_natural = -1``.
    calibration : GeometricCalibration, path, "default" or None, optional
        Passed to :func:`geometric_estimate` (the features do not depend on it).

    Returns
    -------
    features : numpy.ndarray
        Shape ``(len(FEATURE_NAMES),)``, float64, finite.
    estimate : GeometricResult or None
        None if the geometric chain raised :class:`SignalError` (features filled).

    Raises
    ------
    SignalError
        If the window is not a finite, non-constant 1-D signal of at least 32 samples.
    """
    a, est = window_geometry(accel, fs_hz, calibration)
    f = np.array([FILL_VALUES[n] for n in FEATURE_NAMES], dtype=np.float64)

    skew, kurt = _moments(a)
    f[_INDEX["kurtosis"]] = kurt
    f[_INDEX["abs_skewness"]] = abs(skew)
    f[_INDEX["crest_factor"]] = float(np.max(np.abs(a)))
    f[_INDEX["peak_to_peak"]] = float(np.ptp(a))

    if est is None:
        try:
            period = dominant_period(a)
        except SignalError:
            period = float("nan")
    else:
        period = est.period_samples
    fn = natural_frequency_hz
    if fn is not None and np.isfinite(fn) and fn > 0 and np.isfinite(period):
        f[_INDEX["period_natural"]] = period * float(fn) / float(fs_hz)
    if est is None:
        return f, None

    n_periods = a.size / period
    sep = est.separation
    f[_INDEX["geometry_ok"]] = 1.0
    f[_INDEX["impacts_per_period"]] = est.impacts.size / n_periods
    f[_INDEX["separability"]] = sep.separability
    if np.isfinite(sep.mode_ratio) and sep.mode_ratio > 0:
        f[_INDEX["log10_mode_ratio"]] = math.log10(sep.mode_ratio)
    q50, q90, q99 = _hist_quantiles(sep.counts, sep.edges, (0.5, 0.9, 0.99))
    f[_INDEX["log10_tangent_q50"]] = q50
    f[_INDEX["log10_tangent_q90"]] = q90
    f[_INDEX["log10_tangent_q99"]] = q99
    f[_INDEX["log10_tangent_q99_over_q50"]] = q99 - q50

    if est.contact_detected:
        f[_INDEX["contact_detected"]] = 1.0
        for name in (
            "gradient_before_deg",
            "gradient_after_deg",
            "polynomial_before_deg",
            "polynomial_after_deg",
        ):
            f[_INDEX[name]] = getattr(est, name)
        f[_INDEX["polynomial_before_std_deg"]] = float(np.std(est.orbit_before_deg))
        f[_INDEX["polynomial_after_std_deg"]] = float(np.std(est.orbit_after_deg))
        f[_INDEX["n_orbits_per_period"]] = est.n_orbits / n_periods
        f[_INDEX["contact_fraction"]] = est.contact_fraction
        sign = est.polarity if est.polarity != 0 else (1 if skew >= 0 else -1)
        f[_INDEX["spike_width_half_height"]] = _spike_width(sign * a, est.impacts, period)

    # Defensive: a degenerate window must never leak NaN/inf into a model.
    bad = ~np.isfinite(f)
    if bad.any():
        f[bad] = [FILL_VALUES[FEATURE_NAMES[i]] for i in np.flatnonzero(bad)]
    return f, est


def inclination_features(
    accel: ArrayLike, fs_hz: float, natural_frequency_hz: float | None = None
) -> np.ndarray:
    """Feature vector of one acceleration window (see the module notes).

    Parameters
    ----------
    accel : array_like
        Acceleration window (any gain, either polarity).
    fs_hz : float
        Sampling rate in Hz.
    natural_frequency_hz : float or None, optional
        Natural frequency if known (only feature ``period_natural`` uses it).

    Returns
    -------
    numpy.ndarray
        Float64 vector of length ``len(FEATURE_NAMES)``, free of NaN and inf.

    Raises
    ------
    SignalError
        If the window is not a finite, non-constant 1-D signal of at least 32 samples.
    """
    return features_and_estimate(accel, fs_hz, natural_frequency_hz)[0]


def _rows(args: tuple[list[np.ndarray], list[float], list[float | None]]) -> np.ndarray:
    windows, fs, fn = args
    out = np.empty((len(windows), len(FEATURE_NAMES)), dtype=np.float64)
    for i, (w, f, n) in enumerate(zip(windows, fs, fn, strict=True)):
        out[i] = inclination_features(w, f, n)
    return out


def feature_matrix(
    windows: Sequence[ArrayLike],
    fs_hz: float | ArrayLike,
    natural_frequency_hz: float | ArrayLike | None = None,
    n_jobs: int = 1,
) -> np.ndarray:
    """Features of many windows, optionally in worker processes.

    Parameters
    ----------
    windows : sequence of array_like
        Acceleration windows (lengths may differ).
    fs_hz : float or array_like
        One sampling rate for all windows or one per window.
    natural_frequency_hz : float, array_like or None, optional
        Natural frequency for all windows, one per window, or None (unknown).
    n_jobs : int, optional
        Worker processes (1: in this process; -1: one per CPU). Each worker
        gets a contiguous chunk, so the result does not depend on `n_jobs`.

    Returns
    -------
    numpy.ndarray
        Shape ``(len(windows), len(FEATURE_NAMES))``, float64.
    """
    n = len(windows)
    fs = np.broadcast_to(np.asarray(fs_hz, dtype=np.float64), (n,)).tolist()
    if natural_frequency_hz is None:
        fn: list[float | None] = [None] * n
    else:
        if not np.isscalar(natural_frequency_hz):  # None entries mean unknown
            natural_frequency_hz = [np.nan if v is None else v for v in natural_frequency_hz]
        fn = np.broadcast_to(np.asarray(natural_frequency_hz, np.float64), (n,)).tolist()
    ws = [np.asarray(w) for w in windows]
    if n_jobs < 0:
        n_jobs = os.cpu_count() or 1
    n_jobs = max(1, min(n_jobs, n))
    if n == 0:
        return np.empty((0, len(FEATURE_NAMES)), dtype=np.float64)
    if n_jobs == 1:
        return _rows((ws, fs, fn))
    bounds = np.linspace(0, n, 4 * n_jobs + 1).astype(int)
    chunks = [
        (ws[lo:hi], fs[lo:hi], fn[lo:hi])
        for lo, hi in zip(bounds[:-1], bounds[1:], strict=True)
        if hi > lo
    ]
    with ProcessPoolExecutor(n_jobs) as pool:
        return np.concatenate(list(pool.map(_rows, chunks)))
