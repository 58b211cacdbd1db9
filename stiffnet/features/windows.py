"""Model windows: how a recording is cut, and the CNN's canonical input (numpy/scipy only).

Cutting. A model window holds
:data:`stiffnet.config.window.WINDOW_PERIODS` natural periods (16: the
dataset's window and the CNN's canonical window), i.e. ``round(periods * fs / f_n)``
samples at the recording's own rate (:func:`window_length`, the dataset's
rounding rule); consecutive windows start ``hop`` samples apart
(:func:`window_starts`, non-overlapping by default) and the tail that does not
fill a whole window is not used.

The CNN of ``training/families/cnn/`` sees every window in one canonical form, so that
the sampling rate, the sensor gain and the sensor polarity do not matter:

1. **Time base.** The window is resampled to ``rate`` samples per *natural*
   period ``1 / f_n`` (so the natural frequency must be known). Method: when
   the window is sampled faster than ``1.1 * rate`` per period, a zero-phase
   8th-order Butterworth low-pass (``sosfiltfilt``) at 0.45 of the *target*
   sampling rate removes what would alias; then the signal is linearly
   interpolated at the canonical instants ``k * T / rate``. Interpolation keeps
   the exact ratio ``fs / (rate f_n)`` (``resample_poly`` would need a rational
   approximation of it, i.e. a slight time warp). Slower windows are only
   interpolated (no information is added).
2. **Length.** The canonical window holds ``periods`` natural periods
   (``rate * periods`` samples): a longer window is cropped around its centre,
   a shorter one is zero-padded at the end (after normalisation zero is the
   mean, so padding is neutral).
3. **Polarity.** Flipped so that impact spikes point up - the rule of
   :mod:`stiffnet.features.inclination_features`: impacts are detected on the
   Savitzky-Golay-smoothed, standardised window at its own rate
   (:func:`stiffnet.nlts.detect_impacts`, at most one per quarter natural
   period) and their sign taken by the geometric method's polarity rule
   (:func:`stiffnet.geometry.estimate.impact_polarity`); without impacts the sign of the
   skewness decides.
4. **Gain.** The mean is removed and the window divided by its standard
   deviation (over the valid, unpadded samples). The std is the scale the
   inclination features use; it is not a robust scale in the MAD sense, but
   the MAD of a window with sparse spikes is dominated by the slow forced
   response and varies more between classes, and the std never vanishes for a
   non-constant window.

One implementation, batched: :func:`canonical_windows` normalises many windows
of one length and rate at once (the Butterworth design is cached per rate; the
standardisation, smoothing, zero-phase filtering and linear interpolation run on
a 2-D array, and the polarity rule's peak search runs once over the rows joined
(:func:`canonical_polarities`, equal to the per-row rule to the last bit: tested)).
:func:`canonical_window` is its one-window case with argument checks, and
:func:`window_tensor` feeds the training data (windows of varied rates) through
it window by window and a recording's equal windows (the predictor) in one call.

So ``canonical_window(g * a, ...)`` equals ``canonical_window(a, ...)`` for
any gain ``g != 0`` up to floating-point rounding.

:func:`embedded_channels` turns a canonical window into the CNN's input: delay
copies ``x(t), x(t + d), x(t + 2 d)`` stacked as channels, the delay
``d = round(0.18 * rate)`` canonical samples (0.18 natural periods: the delay
rule of the geometric method, :data:`DELAY_FRACTION`). Shifted copies are
zero-padded at the end so all channels keep length ``L``.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike
from scipy.signal import butter, find_peaks, savgol_filter, sosfiltfilt

from stiffnet.config.window import CANONICAL_RATE, DELAY_FRACTION, WINDOW_PERIODS
from stiffnet.errors import ConfigError, SignalError
from stiffnet.geometry.estimate import impact_polarity, smoothing_window
from stiffnet.nlts._validate import as_signal
from stiffnet.nlts.preprocess import MAD_TO_SIGMA
from stiffnet.recordings.base import check_rate

#: Bumped whenever the canonical window's definition changes (recorded in model metadata).
WINDOW_VERSION = 1
#: Default canonical samples per natural period.
DEFAULT_RATE = CANONICAL_RATE
#: Default natural periods per canonical window.
DEFAULT_PERIODS = WINDOW_PERIODS
#: Anti-alias cut-off as a fraction of the canonical sampling rate.
CUTOFF_FRACTION = 0.45
#: ``k`` of :func:`stiffnet.nlts.preprocess.detect_impacts` (its default) in the polarity rule.
IMPACT_K = 8.0
#: Human-readable description stored in model metadata.
NORMALISATION = "mean removed, divided by std of the valid samples; spikes up; zero-padded"


def window_length(
    fs_hz: float, natural_frequency_hz: float, periods: float = WINDOW_PERIODS
) -> int:
    """Samples in a window of `periods` natural periods (the dataset's rounding rule)."""
    return max(8, int(round(periods * fs_hz / natural_frequency_hz)))


def window_starts(n_samples: int, length: int, hop: int) -> np.ndarray:
    """Start indices of the whole windows of `length` samples, `hop` apart."""
    if n_samples < length:
        return np.empty(0, dtype=np.int64)
    return np.arange(0, n_samples - length + 1, max(1, hop), dtype=np.int64)


def preprocessing_contract(rate: int, periods: int, delays: Sequence[int]) -> dict:
    """The whole input contract of a CNN trained on these windows, for its ONNX metadata.

    Everything a user needs to feed the model from plain onnxruntime: how a
    recording is cut, filtered, resampled, flipped, normalised and embedded
    (the steps of :func:`canonical_window` and :func:`embedded_channels`, in
    order), and how the outputs aggregate per recording.
    """
    return {
        "window_version": WINDOW_VERSION,
        "cut": {
            "window_samples": "max(8, round(window_periods * fs / f_n)) at the recording's rate",
            "hop_samples": "window_samples (non-overlapping, from sample 0)",
            "window_periods": periods,
        },
        "steps": [
            "a = (w - mean(w)) / std(w)  (population std, ddof=0)",
            "polarity: p = fs / f_n samples per natural period; smooth a by Savitzky-Golay "
            "(order 2, window max(5, 2*round(0.04*p)+1) samples); impacts = samples where "
            "|d/dt smooth| exceeds median + 8*1.4826*MAD, at most one per 0.25*p samples; "
            "sign = +1 if the median over impacts of the extreme deviation (within +-2 "
            "samples) from the median signal is > 0, else -1; without impacts the sign of "
            "mean(a**3); a = sign * a",
            f"anti-alias: if p / rate > 1.1, scipy.signal.butter(8, {CUTOFF_FRACTION} * 2 / "
            "(p / rate), output='sos') applied with sosfiltfilt (zero phase)",
            "resample: numpy.interp at input positions k * p / rate, "
            "k = 0 .. floor((len - 1) / (p / rate))",
            "crop the centre rate*window_periods samples (or zero-pad at the end), then "
            "subtract the mean and divide by the std of the valid samples",
            "channels: x[c, t] = c_window[t + delays[c]], zero past the end",
        ],
        "canonical_rate": rate,
        "delays": list(int(d) for d in delays),
        "input": "float32 [N, len(delays), rate * window_periods]",
        "outputs": {
            "probabilities": "softmax over class_names",
            "log_beta": "natural log of beta",
            "log_beta_scale": "log of the expected log-beta error of the window",
            "embedding": "pooled features (the alarm's input)",
        },
        "aggregate": "recording: mean probabilities -> class; mean log_beta over windows whose "
        "own class has contact; scale = sqrt(mean(exp(2*log_beta_scale)) + var(log_beta)); "
        "interval exp(mean +- conformal_quantile_recording * scale)",
    }


def default_delays(
    rate: int = DEFAULT_RATE, n_channels: int = 3, delay_fraction: float = DELAY_FRACTION
) -> tuple[int, ...]:
    """Delays ``(0, d, 2 d, ...)`` with ``d = max(1, round(delay_fraction * rate))``."""
    d = max(1, int(round(delay_fraction * rate)))
    return tuple(k * d for k in range(n_channels))


@lru_cache(maxsize=64)
def _antialias(ratio: float) -> np.ndarray:
    """The zero-phase low-pass for `ratio` input samples per canonical sample (cached)."""
    return butter(8, CUTOFF_FRACTION * 2.0 / ratio, output="sos")


def _smoothed_indicator(
    a: np.ndarray, period: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The polarity rule's smoothed windows, impact indicator, its thresholds and separation."""
    n = a.shape[1]
    win = min(smoothing_window(period), n - (1 - n % 2))
    s = savgol_filter(a, win, 2, mode="interp", axis=1) if win >= 3 else a
    sep = max(1, int(0.25 * period))
    # the indicator and its robust threshold for all rows at once (detect_impacts' numbers)
    ind = np.abs(np.gradient(s, axis=1))
    med = np.median(ind, axis=1)
    thr = med + IMPACT_K * MAD_TO_SIGMA * np.median(np.abs(ind - med[:, None]), axis=1)
    return s, ind, thr, sep


def _row_polarity(a: np.ndarray, s: np.ndarray, ind: np.ndarray, thr: float, sep: int) -> float:
    """The polarity rule on one row (the reference the batched rule reproduces)."""
    peaks, _ = find_peaks(ind, height=float(thr), distance=sep)
    pol = impact_polarity(s, peaks.astype(np.int64))
    if pol == 0:
        pol = 1 if float(np.mean(a**3)) >= 0 else -1
    return float(pol)


def _first_medians(x: np.ndarray, count: np.ndarray) -> np.ndarray:
    """``np.median(x[i, :count[i]])`` of every row at once (counts >= 1), to the last bit.

    ``np.median`` is the mean of the two middle elements, ``(a + b) / 2`` (one element
    when the count is odd: ``(a + a) / 2 == a``).
    """
    col = np.arange(x.shape[1])[None, :]
    ordered = np.sort(np.where(col < count[:, None], x, np.inf), axis=1)
    rows = np.arange(x.shape[0])
    return (ordered[rows, (count - 1) // 2] + ordered[rows, count // 2]) / 2


def _rows_peaks(
    ind: np.ndarray, thr: np.ndarray, sep: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``find_peaks(ind[i], height=thr[i], distance=sep)`` of every row, in one call.

    Samples below their row's threshold become -inf (a peak at or above it stays a local
    maximum, and nothing below it can be one), and the rows are joined with ``2 sep + 3``
    samples of +inf between them: a row's first and last samples stay non-peaks (as at a
    row's own edges), and the separator's own peak lies more than `sep` from any row
    sample, so no row's peaks suppress another's. Returns the rows and in-row positions of
    the peaks (sorted), and the rows whose candidates have tied heights: there the
    distance rule's choice depends on the sort's order of ties, so those rows take the
    per-row call.
    """
    rows, n = ind.shape
    gap = 2 * sep + 3
    stride = n + gap
    joined = np.full((rows, stride), np.inf)
    joined[:, :n] = np.where(ind >= thr[:, None], ind, -np.inf)
    joined = joined.reshape(-1)[: rows * stride - gap]
    cand, _ = find_peaks(joined)
    row, pos = np.divmod(cand, stride)
    inside = pos < n
    row, h = row[inside], joined[cand[inside]]
    key = np.lexsort((h, row))
    r, h = row[key], h[key]
    tied = np.unique(r[1:][(r[1:] == r[:-1]) & (h[1:] == h[:-1])])
    peaks, _ = find_peaks(joined, distance=sep)
    row, pos = np.divmod(peaks, stride)
    inside = pos < n
    return row[inside], pos[inside], tied


def canonical_polarities(a: np.ndarray, period: float) -> np.ndarray:
    """Row-wise sign that makes the impact spikes of standardised windows point up.

    The rule of :mod:`stiffnet.features.inclination_features`: Savitzky-Golay smoothing
    (order 2, :func:`stiffnet.geometry.estimate.smoothing_window`), impacts as
    :func:`stiffnet.nlts.preprocess.detect_impacts` finds them (``|gradient|``
    above median + 8 * 1.4826 * MAD, at most one per quarter natural period),
    their sign by :func:`stiffnet.geometry.estimate.impact_polarity`; without
    impacts the sign of the skewness decides.

    Batched over rows with the per-row rule's exact numbers: one peak search over the
    joined rows (:func:`_rows_peaks`), the medians of :func:`impact_polarity` over each
    row's span and impacts with ``np.median``'s arithmetic (:func:`_first_medians`).

    Parameters
    ----------
    a : numpy.ndarray
        Standardised windows at their own rate, shape ``(N, n)``.
    period : float
        Natural period in samples of `a`.

    Returns
    -------
    numpy.ndarray
        ``(N,)`` of +1.0 / -1.0 (never 0).
    """
    s, ind, thr, sep = _smoothed_indicator(a, period)
    rows, n = a.shape
    row, pos, tied = _rows_peaks(ind, thr, sep)
    count = np.bincount(row, minlength=rows)
    out = np.empty(rows)
    has = count > 0
    if has.any():
        # impact_polarity: the extreme deviation within +-2 samples of each impact from
        # the median over the impacts' span, then the median of those extremes
        first = np.searchsorted(row, np.arange(rows))
        lo = np.maximum(0, pos[np.minimum(first, row.size - 1)] - 1)
        hi = pos[np.maximum(first + count - 1, 0)] + 2
        centre = np.zeros(rows)
        for i in np.flatnonzero(has):  # the span differs per row (a loop costs no more)
            centre[i] = np.median(s[i, lo[i] : hi[i]])
        win = np.clip(pos[:, None] + np.arange(-2, 3)[None, :], 0, n - 1)
        dev = s[row[:, None], win] - centre[row, None]
        ext = dev[np.arange(dev.shape[0]), np.argmax(np.abs(dev), axis=1)]
        slot = np.arange(row.size) - first[row]
        table = np.zeros((rows, int(count.max())))
        table[row, slot] = ext
        out[has] = np.where(_first_medians(table[has], count[has]) > 0, 1.0, -1.0)
    for i in np.flatnonzero(~has):  # no impacts: the skewness
        out[i] = 1.0 if float(np.mean(a[i] ** 3)) >= 0 else -1.0
    for i in tied:
        out[i] = _row_polarity(a[i], s[i], ind[i], thr[i], sep)
    return out


def _polarities_per_row(a: np.ndarray, period: float) -> np.ndarray:
    """:func:`canonical_polarities` row by row (the reference its tests compare with)."""
    s, ind, thr, sep = _smoothed_indicator(a, period)
    return np.array([_row_polarity(a[i], s[i], ind[i], thr[i], sep) for i in range(len(a))])


def canonical_windows(
    windows: ArrayLike,
    fs_hz: float,
    natural_frequency_hz: float,
    rate: int = DEFAULT_RATE,
    periods: int = DEFAULT_PERIODS,
) -> np.ndarray:
    """Canonical form of equal-length windows sampled at one rate (see the module notes).

    Parameters
    ----------
    windows : array_like
        Shape ``(N, n)``, at least 32 samples each, none constant.
    fs_hz, natural_frequency_hz : float
        Sampling rate and natural frequency in Hz.
    rate, periods : int, optional
        Canonical samples per natural period and natural periods per window.

    Returns
    -------
    numpy.ndarray
        float32, shape ``(N, rate * periods)``.

    Raises
    ------
    SignalError
        If a window is constant, or the windows are not ``(N, n >= 32)``.
    """
    a = np.asarray(windows, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] < 32:
        raise SignalError(f"expected windows of at least 32 samples, got shape {a.shape}")
    sd = a.std(axis=1, keepdims=True)
    if np.any(~(sd > 0)):
        raise SignalError("acceleration window is constant")
    a = (a - a.mean(axis=1, keepdims=True)) / sd
    period = float(fs_hz) / float(natural_frequency_hz)  # natural period in samples
    a = a * canonical_polarities(a, period)[:, None]

    ratio = period / rate  # input samples per canonical sample
    n_avail = int(np.floor((a.shape[1] - 1) / ratio)) + 1
    if ratio > 1.1:
        a = sosfiltfilt(_antialias(ratio), a, axis=1)
    t = np.arange(n_avail, dtype=np.float64) * ratio
    i0 = np.minimum(np.floor(t).astype(np.int64), a.shape[1] - 1)
    i1 = np.minimum(i0 + 1, a.shape[1] - 1)
    frac = t - i0
    c = a[:, i0] * (1.0 - frac) + a[:, i1] * frac  # linear interpolation, row-wise
    n = rate * periods
    if c.shape[1] > n:
        start = (c.shape[1] - n) // 2
        c = c[:, start : start + n]
    c = c - c.mean(axis=1, keepdims=True)
    sd = c.std(axis=1, keepdims=True)
    if np.any(~(sd > 0)):
        raise SignalError("acceleration window is constant after resampling")
    out = np.zeros((a.shape[0], n), dtype=np.float32)
    out[:, : c.shape[1]] = c / sd
    return out


def canonical_window(
    accel: ArrayLike,
    fs_hz: float,
    natural_frequency_hz: float,
    rate: int = DEFAULT_RATE,
    periods: int = DEFAULT_PERIODS,
) -> np.ndarray:
    """Resampled, cropped, polarity- and gain-normalised window (see the module notes).

    Parameters
    ----------
    accel : array_like
        Acceleration window (any gain, either polarity), at least 32 samples.
    fs_hz : float
        Sampling rate in Hz.
    natural_frequency_hz : float
        Natural frequency of the oscillator in Hz.
    rate : int, optional
        Canonical samples per natural period.
    periods : int, optional
        Natural periods in the canonical window.

    Returns
    -------
    numpy.ndarray
        float32, shape ``(rate * periods,)``.

    Raises
    ------
    SignalError
        If the window is not a finite, non-constant 1-D signal of at least 32 samples.
    ConfigError
        If a rate, frequency or length is not positive.
    """
    fs_hz = check_rate(fs_hz, "fs_hz", ConfigError)
    if natural_frequency_hz is None or not (
        np.isfinite(natural_frequency_hz) and natural_frequency_hz > 0
    ):
        raise ConfigError(
            f"natural_frequency_hz must be a positive number, got {natural_frequency_hz!r}"
        )
    if int(rate) < 4 or int(periods) < 1:
        raise ConfigError(f"rate must be >= 4 and periods >= 1, got {rate} and {periods}")
    a = as_signal(accel, 32, "acceleration")
    return canonical_windows(a[None, :], fs_hz, natural_frequency_hz, int(rate), int(periods))[0]


def embedded_channels(w: ArrayLike, delays: Sequence[int] | None = None) -> np.ndarray:
    """Delay-embedded channels of canonical windows: ``out[..., c, t] = w[..., t + delays[c]]``.

    Parameters
    ----------
    w : array_like
        Canonical window, shape ``(L,)``, or windows ``(N, L)``.
    delays : sequence of int, optional
        Non-negative delays in canonical samples; default :func:`default_delays`
        for the default rate (``(0, 6, 12)``: 0.18 natural periods at 32 per period).

    Returns
    -------
    numpy.ndarray
        float32, shape ``(len(delays), L)`` (``(N, len(delays), L)`` for windows);
        samples beyond the end are zero.
    """
    w = np.asarray(w, dtype=np.float32)
    if w.ndim not in (1, 2):
        raise ConfigError(f"window must be 1-D (or N windows, 2-D), got shape {w.shape}")
    delays = default_delays() if delays is None else tuple(int(d) for d in delays)
    if not delays or min(delays) < 0:
        raise ConfigError(f"delays must be non-empty and non-negative, got {delays}")
    n = w.shape[-1]
    out = np.zeros((*w.shape[:-1], len(delays), n), dtype=np.float32)
    for c, d in enumerate(delays):
        if d < n:
            out[..., c, : n - d] = w[..., d:]
    return out


def window_tensor(
    windows: Sequence[ArrayLike] | np.ndarray,
    fs_hz: float | ArrayLike,
    natural_frequency_hz: float | ArrayLike,
    rate: int = DEFAULT_RATE,
    periods: int = DEFAULT_PERIODS,
    delays: Sequence[int] | None = None,
) -> np.ndarray:
    """CNN input of many windows: shape ``(N, len(delays), rate * periods)``, float32.

    `fs_hz` and `natural_frequency_hz` are scalars or one value per window. A
    2-D array of windows with one rate (a recording's windows, the predictor)
    goes through :func:`canonical_windows` in one call; a list of windows of
    varied lengths or rates (the training data) one window at a time.
    """
    delays = default_delays(rate) if delays is None else tuple(int(d) for d in delays)
    one_rate = np.ndim(fs_hz) == 0 and np.ndim(natural_frequency_hz) == 0
    if isinstance(windows, np.ndarray) and windows.ndim == 2 and one_rate:
        c = canonical_windows(windows, float(fs_hz), float(natural_frequency_hz), rate, periods)
        return embedded_channels(c, delays)
    n = len(windows)
    fs = np.broadcast_to(np.asarray(fs_hz, dtype=np.float64), (n,))
    fn = np.broadcast_to(np.asarray(natural_frequency_hz, dtype=np.float64), (n,))
    out = np.empty((n, len(delays), rate * periods), dtype=np.float32)
    for i in range(n):
        out[i] = embedded_channels(
            canonical_window(windows[i], float(fs[i]), float(fn[i]), rate, periods), delays
        )
    return out
