"""Canonical acceleration windows for the 1-D CNN (numpy/scipy only).

The CNN of ``training/cnn.py`` sees every window in one canonical form, so that
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
   :mod:`stiffnet.features.inclination`: impacts are detected on the
   Savitzky-Golay-smoothed, standardised window at its own rate
   (:func:`stiffnet.nlts.detect_impacts`, at most one per quarter natural
   period) and their sign taken by the geometric method's polarity rule
   (``stiffnet.geometry.estimate._polarity``); without impacts the sign of the
   skewness decides.
4. **Gain.** The mean is removed and the window divided by its standard
   deviation (over the valid, unpadded samples). The std is the scale the
   inclination features use; it is not a robust scale in the MAD sense, but
   the MAD of a window with sparse spikes is dominated by the slow forced
   response and varies more between classes, and the std never vanishes for a
   non-constant window.

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

import numpy as np
from numpy.typing import ArrayLike
from scipy.signal import butter, sosfiltfilt

from stiffnet.errors import ConfigError, SignalError
from stiffnet.geometry.estimate import _polarity, smoothing_window
from stiffnet.nlts._validate import as_signal
from stiffnet.nlts.preprocess import detect_impacts, savgol_smooth

#: Bumped whenever the canonical window's definition changes (recorded in model metadata).
WINDOW_VERSION = 1
#: Default canonical samples per natural period.
DEFAULT_RATE = 32
#: Default natural periods per canonical window.
DEFAULT_PERIODS = 16
#: Delay of the embedded channels in natural periods (the geometric method's rule).
DELAY_FRACTION = 0.18
#: Anti-alias cut-off as a fraction of the canonical sampling rate.
CUTOFF_FRACTION = 0.45
#: Human-readable description stored in model metadata.
NORMALISATION = "mean removed, divided by std of the valid samples; spikes up; zero-padded"


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


def default_delays(rate: int = DEFAULT_RATE, n_channels: int = 3) -> tuple[int, ...]:
    """Delays ``(0, d, 2 d, ...)`` with ``d = max(1, round(DELAY_FRACTION * rate))``."""
    d = max(1, int(round(DELAY_FRACTION * rate)))
    return tuple(k * d for k in range(n_channels))


def canonical_polarity(a: np.ndarray, period: float) -> int:
    """+1 if the impact spikes of the standardised window `a` point up, -1 if down.

    Parameters
    ----------
    a : numpy.ndarray
        Standardised window at its own rate.
    period : float
        Natural period in samples of `a`.

    Returns
    -------
    int
        The sign to multiply `a` with (never 0).
    """
    win = min(smoothing_window(period), a.size - (1 - a.size % 2))
    s = savgol_smooth(a, win, 2) if win >= 3 else a
    impacts = detect_impacts(s, min_separation=max(1, int(0.25 * period)))
    pol = _polarity(s, impacts)
    if pol == 0:
        pol = 1 if float(np.mean(a**3)) >= 0 else -1
    return pol


def _resample(a: np.ndarray, ratio: float, n_out: int) -> np.ndarray:
    """`a` sampled at ``ratio`` samples per canonical sample -> canonical rate."""
    if ratio > 1.1:
        sos = butter(8, CUTOFF_FRACTION * 2.0 / ratio, output="sos")
        a = sosfiltfilt(sos, a)
    t = np.arange(n_out, dtype=np.float64) * ratio
    return np.interp(t, np.arange(a.size, dtype=np.float64), a)


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
    if not (np.isfinite(fs_hz) and fs_hz > 0):
        raise ConfigError(f"fs_hz must be a positive number, got {fs_hz!r}")
    if natural_frequency_hz is None or not (
        np.isfinite(natural_frequency_hz) and natural_frequency_hz > 0
    ):
        raise ConfigError(
            f"natural_frequency_hz must be a positive number, got {natural_frequency_hz!r}"
        )
    if int(rate) < 4 or int(periods) < 1:
        raise ConfigError(f"rate must be >= 4 and periods >= 1, got {rate} and {periods}")
    rate, periods = int(rate), int(periods)
    a = as_signal(accel, 32, "acceleration")
    sd = a.std()
    if not sd > 0:
        raise SignalError("acceleration is constant")
    a = (a - a.mean()) / sd
    period = float(fs_hz) / float(natural_frequency_hz)  # natural period in samples
    a = canonical_polarity(a, period) * a

    ratio = period / rate  # input samples per canonical sample
    n_avail = int(np.floor((a.size - 1) / ratio)) + 1
    c = _resample(a, ratio, n_avail)
    n = rate * periods
    if c.size > n:
        start = (c.size - n) // 2
        c = c[start : start + n]
    c = c - c.mean()
    sd = c.std()
    if not sd > 0:
        raise SignalError("acceleration is constant after resampling")
    out = np.zeros(n, dtype=np.float32)
    out[: c.size] = c / sd
    return out


def embedded_channels(w: ArrayLike, delays: Sequence[int] | None = None) -> np.ndarray:
    """Delay-embedded channels of a canonical window: ``out[c, t] = w[t + delays[c]]``.

    Parameters
    ----------
    w : array_like
        Canonical window, shape ``(L,)``.
    delays : sequence of int, optional
        Non-negative delays in canonical samples; default :func:`default_delays`
        for the default rate (``(0, 6, 12)``: 0.18 natural periods at 32 per period).

    Returns
    -------
    numpy.ndarray
        float32, shape ``(len(delays), L)``; samples beyond the end are zero.
    """
    w = np.asarray(w, dtype=np.float32)
    if w.ndim != 1:
        raise ConfigError(f"window must be 1-D, got shape {w.shape}")
    delays = default_delays() if delays is None else tuple(int(d) for d in delays)
    if not delays or min(delays) < 0:
        raise ConfigError(f"delays must be non-empty and non-negative, got {delays}")
    out = np.zeros((len(delays), w.size), dtype=np.float32)
    for c, d in enumerate(delays):
        if d < w.size:
            out[c, : w.size - d] = w[d:]
    return out


def window_tensor(
    windows: Sequence[ArrayLike],
    fs_hz: float | ArrayLike,
    natural_frequency_hz: float | ArrayLike,
    rate: int = DEFAULT_RATE,
    periods: int = DEFAULT_PERIODS,
    delays: Sequence[int] | None = None,
) -> np.ndarray:
    """CNN input of many windows: shape ``(N, len(delays), rate * periods)``, float32.

    `fs_hz` and `natural_frequency_hz` are scalars or one value per window.
    """
    n = len(windows)
    fs = np.broadcast_to(np.asarray(fs_hz, dtype=np.float64), (n,))
    fn = np.broadcast_to(np.asarray(natural_frequency_hz, dtype=np.float64), (n,))
    delays = default_delays(rate) if delays is None else tuple(delays)
    out = np.empty((n, len(delays), rate * periods), dtype=np.float32)
    for i in range(n):
        out[i] = embedded_channels(
            canonical_window(windows[i], float(fs[i]), float(fn[i]), rate, periods), delays
        )
    return out
