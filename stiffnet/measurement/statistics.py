"""Phase-independent statistics of one acceleration record.

A simulation started from other initial conditions, with another noise
realisation, never matches a measurement sample by sample; what it must match
are the statistics that do not depend on the phase of the record:

==========================  ===============================================================
impact-aligned waveform     mean of the record around every impact spike, aligned on the
                            spike's extremum, time in natural periods (contact + rebound)
spike height / width        median height above the local baseline and time above half
                            height within the spike's lobe (natural periods) of the spikes
                            (on an orbit of n > 1 impacts per repeat, the mean of each
                            impact's median: :func:`orbit_median`)
post-impact ringing         high-passed (> 10 f_n) RMS after the spike over the RMS before
                            it (log10) and the frequency of that ringing (sensor resonance,
                            restraint modes)
free-flight harmonics       amplitudes of the 2nd and 3rd forcing harmonics over the
                            fundamental, least squares on a copy low-passed at 8 f_n (a
                            ringing sensor would leak in) with each spike bridged by a
                            straight line (:func:`bridged_free_flight`)
spectrum                    Welch PSD averaged in 1/5-octave bands of f / f_n (log10)
impact rate                 impacts per forcing period (spikes found on the low-passed
                            copy by a level rule, see :func:`spike_peaks`)
inclination statistics      the geometric method's mean angles before / after impact
                            (:func:`stiffnet.features.inclination_features.window_geometry`)
==========================  ===============================================================

Conventions. Every statistic is gain-free: the record is centred on its median
and divided by a robust scale (1.4826 MAD, dominated by free flight, which an
effect on the contact barely moves). Polarity is made canonical (spikes up,
``y = polarity * z``) from the sign of the skewness, so a sensor mounted the
other way compares as well. Times are in natural periods ``1 / f_n``.

Every statistic moves continuously with the record: widths between interpolated
half-height crossings, windows and bridges with fractional edges around
sub-sample peaks (a fit walks the model's parameters; a statistic counted in
whole samples steps, and the local search stalls on the plateaus between steps).

Low-level functions return whole curves or per-impact vectors; the rules that
reduce them to one number (medians, means) live in :func:`signal_statistics`.
numpy/scipy only.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.fft as sps_fft
import scipy.signal as sps
from numpy.typing import ArrayLike

from stiffnet.errors import SignalError
from stiffnet.geometry.orbit import impact_pattern

#: 1.4826 MAD is the standard deviation of a normal distribution.
_MAD_TO_SIGMA = 1.4826
#: Spikes rise this many robust units above the record's upper quartile.
SPIKE_RISE = 1.5
#: Spikes are detected, and harmonics fitted, below this multiple of f_n (sensor ringing
#: is above it; the forcing's third harmonic below).
DETECTION_LOWPASS = 8.0
#: Aligned window around each spike, natural periods before and after the extremum.
WAVEFORM_BEFORE = 0.25
WAVEFORM_AFTER = 0.5
#: Samples per natural period of the aligned-waveform grid.
WAVEFORM_RATE = 128
#: Ringing is what is left above this multiple of f_n (contact-free motion is far below).
RINGING_HIGHPASS = 10.0
#: Spectrum grid: log-spaced f / f_n from SPECTRUM_LOW to min(SPECTRUM_HIGH, 0.45 fs / f_n).
SPECTRUM_LOW = 0.25
SPECTRUM_HIGH = 60.0
SPECTRUM_POINTS = 96
#: Spectrum bands span grid / BAND_HALF_WIDTH .. grid * BAND_HALF_WIDTH (1/5 octave).
BAND_HALF_WIDTH = 2**0.1
#: Welch segments of this many natural periods.
WELCH_PERIODS = 4.0
#: Harmonics of the forcing fitted in free flight (1 = fundamental).
N_HARMONICS = 3
#: Amplitude ratios below this are floored (a missing harmonic stays a finite number).
HARMONIC_FLOOR = 1e-3
#: The free flight's harmonics bridge each spike over +- this many widths at half height,
#: and at least :data:`BRIDGE_MIN` natural periods (the spike's tails on the low-passed copy).
BRIDGE_WIDTHS = 2.0
BRIDGE_MIN = 0.1


@dataclass
class SignalStatistics:
    """Phase-independent statistics of one record (see the module notes).

    Attributes
    ----------
    fs_hz, natural_frequency_hz, frequency_ratio : float
        Sampling rate, ``f_n`` and the forcing frequency over ``f_n`` used.
    scale : float
        Robust scale the record was divided by (its unit).
    polarity : int
        +1 if spikes point up in the record, -1 if down.
    impacts : numpy.ndarray
        Sample indices of the spike extrema.
    waveform_t, waveform : numpy.ndarray
        Impact-aligned mean waveform (canonical polarity, robust units) against
        time from the extremum in natural periods; empty without impacts.
    spike_height, spike_width : float
        Median spike height (robust units) and full width at half height
        (natural periods), over the orbit's repeat (:func:`orbit_median`); NaN without
        impacts.
    ringing, ringing_frequency : float
        log10 of post-impact over pre-impact high-passed RMS, and the ringing's
        peak frequency over ``f_n``; NaN without impacts.
    harmonics : numpy.ndarray
        Amplitudes of forcing harmonics 1..N over the fundamental (first is 1).
    psd_f, log_psd : numpy.ndarray
        Welch log10 PSD of the normalised record on the grid ``psd_f`` (f / f_n).
    impacts_per_period : float
        Impacts per forcing period.
    inclination_before_deg, inclination_after_deg : float
        Geometric method's mean inclinations (NaN without contact or when not computed).
    """

    fs_hz: float
    natural_frequency_hz: float
    frequency_ratio: float
    scale: float
    polarity: int
    impacts: np.ndarray
    waveform_t: np.ndarray
    waveform: np.ndarray
    spike_height: float
    spike_width: float
    ringing: float
    ringing_frequency: float
    harmonics: np.ndarray
    psd_f: np.ndarray
    log_psd: np.ndarray
    impacts_per_period: float
    inclination_before_deg: float = float("nan")
    inclination_after_deg: float = float("nan")
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def has_impacts(self) -> bool:
        return self.impacts.size > 0

    def scalars(self) -> dict[str, float]:
        """The scalar statistics, JSON-ready (NaN -> None)."""
        values = {
            "spike_height": self.spike_height,
            "spike_width": self.spike_width,
            "ringing": self.ringing,
            "ringing_frequency": self.ringing_frequency,
            "harmonic_2": float(self.harmonics[1]),
            "harmonic_3": float(self.harmonics[2]),
            "impacts_per_period": self.impacts_per_period,
            "inclination_before_deg": self.inclination_before_deg,
            "inclination_after_deg": self.inclination_after_deg,
        }
        return {k: (float(v) if np.isfinite(v) else None) for k, v in values.items()}


# ------------------------------------------------------------------------ low level


def robust_standardise(accel: ArrayLike) -> tuple[np.ndarray, float]:
    """Record centred on its median and divided by 1.4826 MAD; returns it and the scale.

    Raises
    ------
    SignalError
        If the record is not finite or has no spread.
    """
    a = np.asarray(accel, dtype=np.float64)
    if a.ndim != 1 or a.size < 32 or not np.all(np.isfinite(a)):
        raise SignalError("a record must be a finite 1-D signal of at least 32 samples")
    med = float(np.median(a))
    scale = _MAD_TO_SIGMA * float(np.median(np.abs(a - med)))
    if not scale > 0:
        scale = float(np.std(a))
    if not scale > 0:
        raise SignalError("the record is constant")
    return (a - med) / scale, scale


def skew_polarity(z: np.ndarray) -> int:
    """+1 when the spikes point up (positive skewness), -1 when down."""
    return 1 if float(np.mean(z * z * z)) >= 0 else -1


@functools.lru_cache(maxsize=256)
def _butter_sos(wn: float, btype: str) -> np.ndarray:
    """4th-order Butterworth SOS at normalised corner ``wn`` (cached: a fit designs the same
    few filters thousands of times; the design costs as much as the filtering)."""
    return sps.butter(4, wn, btype, output="sos")


def lowpass(y: np.ndarray, cycles_per_sample: float) -> np.ndarray:
    """Zero-phase 4th-order Butterworth low-pass (unchanged when the corner is near Nyquist);
    along the last axis (a 2-D array: each row)."""
    if not cycles_per_sample < 0.45:
        return y
    return sps.sosfiltfilt(_butter_sos(2 * cycles_per_sample, "lowpass"), y, axis=-1)


def spike_peaks(
    y: np.ndarray, smooth: np.ndarray, period_samples: float, rise: float = SPIKE_RISE
) -> np.ndarray:
    """Extrema of the upward spikes of a canonical-polarity, robust-standardised record.

    Detection runs on ``smooth``, the record low-passed at
    :data:`DETECTION_LOWPASS` f_n (:func:`lowpass`): a spike is a peak of it
    standing ``rise`` robust units above its upper quartile (free flight of a
    sinusoid stays within about 0.3 of it), at least a quarter period from a
    higher one; each is then moved to the maximum of the raw record ``y``
    within +-5 % of a period. A level rule on a low-passed copy rather than
    the derivative indicator of :func:`stiffnet.nlts.detect_impacts`: a
    ringing sensor raises the derivative's threshold until real spikes fall
    under it, and adds peaks of its own.
    """
    level = float(np.quantile(smooth, 0.75)) + rise
    found, _ = sps.find_peaks(smooth, height=level, distance=max(1, int(0.25 * period_samples)))
    if found.size == 0:
        return found.astype(np.int64)
    half = max(1, int(round(0.05 * period_samples)))
    idx = np.clip(found[:, None] + np.arange(-half, half + 1)[None, :], 0, y.size - 1)
    peaks = idx[np.arange(idx.shape[0]), np.argmax(y[idx], axis=1)]
    return np.unique(peaks).astype(np.int64)


def aligned_segments(
    y: np.ndarray,
    peaks: np.ndarray,
    samples_per_natural_period: float,
    before: float = WAVEFORM_BEFORE,
    after: float = WAVEFORM_AFTER,
    rate: int = WAVEFORM_RATE,
) -> tuple[np.ndarray, np.ndarray]:
    """Segments of ``y`` around every peak, resampled onto a grid in natural periods.

    Returns
    -------
    t : numpy.ndarray
        Grid, natural periods from the extremum (``-before .. after``).
    segments : numpy.ndarray
        Shape ``(K, len(t))``; peaks too close to an end are left out.
    """
    t = np.arange(-int(before * rate), int(after * rate) + 1) / rate
    n = y.size
    ts = np.asarray(peaks, dtype=np.float64)[:, None] + t[None, :] * samples_per_natural_period
    ts = ts[(ts[:, 0] >= 0) & (ts[:, -1] <= n - 1)]
    if ts.shape[0] == 0:
        return t, np.empty((0, t.size))
    return t, np.interp(ts.ravel(), np.arange(n, dtype=np.float64), y).reshape(ts.shape)


def orbit_median(values: np.ndarray, pattern: tuple[int, int] | None) -> float:
    """The typical value of a per-spike quantity on the record's orbit: the median over
    the spikes on a period-1 orbit; on an orbit of ``n > 1`` impacts per repeat, the mean
    of the medians of each of the repeat's ``n`` impacts.

    On such an orbit the spikes alternate (a period-2 orbit's big and small impacts, a
    factor 8 apart behind a stiffening contact), and the plain median of the two groups
    falls in one group or halfway between them by the parity of the spike count, i.e.
    by the record's length: a 4 s recording's 35 spikes gave the small group's height, the
    same orbit simulated over 16 natural periods (14 spikes) the midpoint, 15 tolerances
    apart. Each impact's median, averaged over the repeat, is the same on any length.

    Parameters
    ----------
    values : numpy.ndarray
        One value per spike in time order (consecutive spikes: only the record's ends may
        be left out); NaN where not measured.
    pattern : tuple of int or None
        The orbit ``(n, m)`` (:func:`~stiffnet.geometry.orbit.impact_pattern`); None: no
        repeat named, the plain median.
    """
    v = np.asarray(values, dtype=np.float64)
    n = pattern[0] if pattern is not None else 1
    if n < 2 or v.size < 2 * n:
        return float(np.nanmedian(v))
    phases = [v[k::n] for k in range(n)]
    return float(np.mean([np.nanmedian(x) for x in phases if np.isfinite(x).any()]))


def spike_heights_widths(t: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Height above the pre-impact baseline and width at half height of each spike.

    The baseline is the median of the segment from 0.25 to 0.1 natural periods
    before the extremum (free flight). The width is the time the spike's lobe
    (from its last departure from the baseline before the extremum to its first
    return after it) spends above half height, in natural periods, with the
    half-height crossings interpolated linearly between grid points. For a
    single-humped spike it is the full width at half height; it is a time above
    a level rather than the span between the first crossings on either side
    because a ringing sensor rides on a soft contact's pulse: when a trough of
    the ringing reaches half height, the first crossing jumps from the end of
    the pulse to the first trough (on the independent rig at beta 9 with a
    237-Hz mount, 0.067 against 0.034 natural periods for the same pulse,
    4.5 tolerances of ``spike_width`` and, through the bridges, 3.2 of
    ``harmonic_2``), whereas the time above half height only loses the trough's
    short dip. Either way a width moves continuously with the record (counted
    in whole grid steps it jumped by 1/8 at a width of 8 steps, 0.8 tolerances).
    """
    if segments.shape[0] == 0:
        return np.empty(0), np.empty(0)
    pre = (t >= -0.25) & (t <= -0.1)
    base = np.median(segments[:, pre], axis=1)
    i0 = int(np.argmin(np.abs(t)))
    height = segments[:, i0] - base
    level = (base + 0.5 * height)[:, None]
    n = segments.shape[1]
    grid = np.arange(n)[None, :]
    at_base = segments <= base[:, None]
    first = np.maximum(np.where(at_base & (grid <= i0), grid, -1).max(axis=1), 0)
    last = np.minimum(np.where(at_base & (grid >= i0), grid, n).min(axis=1), n - 1)
    steps = np.arange(n - 1)[None, :]
    in_lobe = (steps >= first[:, None]) & (steps < last[:, None])
    above = _fraction_above(segments[:, :-1], segments[:, 1:], level)
    widths = np.where(height > 0, np.sum(above * in_lobe, axis=1) * (t[1] - t[0]), np.nan)
    return height, widths


def _fraction_above(a: np.ndarray, b: np.ndarray, level: np.ndarray) -> np.ndarray:
    """Fraction of each grid step from ``a`` to ``b`` that the straight line between them
    spends above ``level``."""
    up, down = a > level, b > level
    with np.errstate(divide="ignore", invalid="ignore"):
        cut = np.where(up, (a - level) / (a - b), (b - level) / (b - a))
    return np.where(up & down, 1.0, np.where(up != down, cut, 0.0))


def highpass(y: np.ndarray, fs_hz: float, cutoff_hz: float) -> np.ndarray:
    """Zero-phase 4th-order Butterworth high-pass (zero when the cutoff is near Nyquist);
    along the last axis."""
    if cutoff_hz >= 0.45 * fs_hz:
        return np.zeros_like(y)
    return sps.sosfiltfilt(_butter_sos(2 * cutoff_hz / fs_hz, "highpass"), y, axis=-1)


def ringing_curves(
    r: np.ndarray, peaks: np.ndarray, samples_per_natural_period: float, start: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per-impact high-passed RMS after and before the spike.

    After: from ``start`` to ``start + 0.25`` natural periods past the
    extremum; before: the mirror window ``-start - 0.25 .. -start``. Each
    sample weighs by its overlap with the window, so the RMS moves
    continuously with ``start`` (which follows the spike's width).
    """
    p_n = samples_per_natural_period
    s0, s1 = start * p_n, (start + 0.25) * p_n
    k = np.arange(int(np.floor(s0 - 0.5)), int(np.ceil(s1 + 0.5)) + 1)
    w = np.clip(np.minimum(k + 0.5, s1) - np.maximum(k - 0.5, s0), 0.0, 1.0)
    k, w = k[w > 0], w[w > 0]
    p = np.asarray(peaks, dtype=np.int64)
    if k.size == 0:
        return np.empty(0), np.empty(0)
    p = p[(p - k[-1] >= 0) & (p + k[-1] < r.size)]
    if p.size == 0:
        return np.empty(0), np.empty(0)
    post = np.sqrt(r[p[:, None] + k[None, :]] ** 2 @ w / w.sum())
    pre = np.sqrt(r[p[:, None] - k[None, :]] ** 2 @ w / w.sum())
    return post, pre


def ringing_spectrum(
    r: np.ndarray, peaks: np.ndarray, samples_per_natural_period: float, start: float
) -> tuple[np.ndarray, np.ndarray]:
    """Mean periodogram of the post-impact high-passed windows (frequency in cycles/sample)."""
    p_n = samples_per_natural_period
    a0, a1 = int(round(start * p_n)), int(round((start + 0.25) * p_n)) + 1
    p = np.asarray(peaks, dtype=np.int64)
    p = p[p + a1 <= r.size]
    if p.size == 0 or a1 - a0 < 8:
        return np.empty(0), np.empty(0)
    nfft = 4 * (a1 - a0)
    segs = r[p[:, None] + np.arange(a0, a1)[None, :]] * np.hanning(a1 - a0)[None, :]
    spec = np.mean(np.abs(np.fft.rfft(segs, nfft, axis=1)) ** 2, axis=0)
    return np.fft.rfftfreq(nfft), spec


def refined_peaks(y: np.ndarray, peaks: np.ndarray) -> np.ndarray:
    """Sub-sample positions of the extrema ``peaks`` of ``y`` (vertex of the parabola
    through each and its two neighbours; one at an end stays where it is)."""
    p = np.asarray(peaks, dtype=np.int64)
    inner = (p > 0) & (p < y.size - 1)
    out = p.astype(np.float64)
    q = p[inner]
    a, b, c = y[q - 1], y[q], y[q + 1]
    curv = a - 2 * b + c
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(curv < 0, 0.5 * (a - c) / curv, 0.0)
    out[inner] = q + np.clip(delta, -0.5, 0.5)
    return out


def spike_spans(n: int, centres: np.ndarray, half_width: float) -> list[tuple[float, float]]:
    """The record's stretches within ``half_width`` samples of a spike centre (fractional
    edges, clipped to the record, overlapping ones merged), in time order."""
    spans: list[tuple[float, float]] = []
    for c in np.sort(np.asarray(centres, dtype=np.float64)):
        lo, hi = max(0.0, c - half_width), min(n - 1.0, c + half_width)
        if spans and lo <= spans[-1][1]:
            spans[-1] = (spans[-1][0], max(spans[-1][1], hi))
        elif hi > lo:
            spans.append((lo, hi))
    return spans


def bridged_free_flight(y: np.ndarray, spans: Sequence[tuple[float, float]]) -> np.ndarray:
    """``y`` with every span replaced by the straight line between its values at the span's
    (fractional) edges, read by linear interpolation.

    The free flight's harmonics are fitted on this copy over the whole record
    rather than on the free-flight samples alone: on a mask that leaves out the
    same part of every forcing period the harmonics are far from orthogonal, and
    the least squares amplify a small difference of the waveforms near the
    mask's edge (on the independent rig, moving the edge by 0.05 natural periods
    moved a recording's ``harmonic_2`` difference by 3 to 10 tolerances). A
    bridge is continuous in its edges: a sample crosses an edge where the line
    meets the record.
    """
    out = np.array(y, dtype=np.float64, copy=True)
    if not len(spans):
        return out
    lo, hi = np.asarray(spans, dtype=np.float64).T
    # every span's inner samples at once (a loop per span cost as much as the fit it feeds)
    first = np.floor(lo).astype(np.int64) + 1
    count = np.maximum(np.ceil(hi).astype(np.int64) - first, 0)
    which = np.repeat(np.arange(lo.size), count)
    i = first[which] + (np.arange(which.size) - np.repeat(np.cumsum(count) - count, count))
    a, b = _read_at(y, lo), _read_at(y, hi)
    a, b, lo, hi = a[which], b[which], lo[which], hi[which]
    out[i] = a + (b - a) * (i - lo) / (hi - lo)
    return out


def _read_at(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``y`` read at fractional indices ``x`` by linear interpolation."""
    i = np.minimum(np.floor(x).astype(np.int64), y.size - 2)
    return y[i] + (x - i) * (y[i + 1] - y[i])


def harmonic_amplitudes(
    y: np.ndarray, frequency_cycles_per_sample: float, mask: np.ndarray, n_harmonics: int
) -> np.ndarray:
    """Least-squares amplitudes of harmonics 1..N of a known frequency on the masked samples."""
    if mask.all():  # the whole record: the design is the same at every evaluation of a fit
        # its pseudo-inverse is kept with it: one matrix product per record instead of an SVD
        # (the SVD was about a sixth of a simulated batch's statistics)
        solver = _harmonic_solver(mask.size, float(frequency_cycles_per_sample), n_harmonics)
        coef = solver @ np.asarray(y, dtype=np.float64)
    else:
        design = _design_at(np.flatnonzero(mask).astype(np.float64), frequency_cycles_per_sample,
                            n_harmonics)  # fmt: skip
        coef, *_ = np.linalg.lstsq(design, y[mask], rcond=None)
    return np.hypot(coef[1::2], coef[2::2])


def _design_at(t: np.ndarray, frequency_cycles_per_sample: float, n_harmonics: int) -> np.ndarray:
    """Columns 1, cos and sin of harmonics 1..N at the sample times ``t``."""
    cols = [np.ones_like(t)]
    for k in range(1, n_harmonics + 1):
        ph = 2 * np.pi * k * frequency_cycles_per_sample * t
        cols += [np.cos(ph), np.sin(ph)]
    return np.column_stack(cols)


@functools.lru_cache(maxsize=64)
def _harmonic_design(n: int, frequency_cycles_per_sample: float, n_harmonics: int) -> np.ndarray:
    """:func:`_design_at` of samples 0..n-1, kept per length and frequency (a campaign's
    simulated rows keep both through a fit; read-only)."""
    design = _design_at(np.arange(n, dtype=np.float64), frequency_cycles_per_sample, n_harmonics)
    design.setflags(write=False)
    return design


@functools.lru_cache(maxsize=64)
def _harmonic_solver(n: int, frequency_cycles_per_sample: float, n_harmonics: int) -> np.ndarray:
    """The least-squares solution operator of :func:`_harmonic_design` (its Moore-Penrose
    pseudo-inverse, ``2 N + 1`` by ``n``): the coefficients of a record are this times the
    record, equal to ``numpy.linalg.lstsq``'s to rounding (the design is well conditioned:
    cosines and sines over many periods). Read-only."""
    solver = np.linalg.pinv(_harmonic_design(n, frequency_cycles_per_sample, n_harmonics))
    solver.setflags(write=False)
    return solver


def welch_log_psd(
    y: np.ndarray, fs_hz: float, natural_frequency_hz: float
) -> tuple[np.ndarray, np.ndarray]:
    """Welch PSD averaged over bands of +-:data:`BAND_HALF_WIDTH` around a log grid of f / f_n.

    Segments of :data:`WELCH_PERIODS` natural periods (Hann, half overlap); the
    grid ends at ``min(SPECTRUM_HIGH, 0.45 fs / f_n)``. Band averages of the
    power (not of its log) keep the harmonic lines and the floor between them
    in proportion: a log PSD sampled between lines would measure only the
    leakage of the window and the last traces of the transient.

    Returns
    -------
    grid : numpy.ndarray
        Band centres, f / f_n.
    log_psd : numpy.ndarray
        log10 of the band-mean PSD (one row per row of a 2-D ``y``).
    """
    y = np.asarray(y)
    nper = int(min(y.shape[-1], max(16, round(WELCH_PERIODS * fs_hz / natural_frequency_hz))))
    f, p = _welch(y, fs_hz, nper)
    hi = min(SPECTRUM_HIGH, 0.45 * fs_hz / natural_frequency_hz)
    grid = np.geomspace(SPECTRUM_LOW, hi, SPECTRUM_POINTS)
    fr = f / natural_frequency_hz
    lo_i = np.searchsorted(fr, grid / BAND_HALF_WIDTH, side="left")
    hi_i = np.searchsorted(fr, grid * BAND_HALF_WIDTH, side="right")
    p2 = p.reshape(-1, p.shape[-1])
    csum = np.concatenate([np.zeros((p2.shape[0], 1)), np.cumsum(p2, axis=1)], axis=1)
    count = hi_i - lo_i
    mean = (csum[:, hi_i] - csum[:, lo_i]) / np.maximum(count, 1)
    if not (count > 0).all():  # a band narrower than the resolution: interpolated
        mean = np.where(count > 0, mean, np.array([np.interp(grid, fr, row) for row in p2]))
    log_psd = np.log10(np.maximum(mean, 1e-30))
    return grid, log_psd.reshape(*p.shape[:-1], grid.size)


@functools.lru_cache(maxsize=64)
def _welch_stft(nperseg: int, fs_hz: float) -> sps.ShortTimeFFT:
    """The short-time transform :func:`scipy.signal.welch` builds for a Hann window of
    ``nperseg`` samples, half overlap, one-sided PSD scaling (kept: its window design and
    scaling cost as much as a short record's transforms)."""
    win = sps.get_window("hann", nperseg)
    return sps.ShortTimeFFT(win, nperseg - nperseg // 2, fs_hz, fft_mode="onesided",
                            mfft=nperseg, scale_to="psd", phase_shift=None)  # fmt: skip


def _welch(y: np.ndarray, fs_hz: float, nperseg: int) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.signal.welch(y, fs_hz, nperseg=nperseg, axis=-1)``, bit for bit, with every
    segment of every row transformed in one call (scipy transforms one segment at a time)."""
    sft = _welch_stft(nperseg, float(fs_hz))
    n, hop = y.shape[-1], sft.hop
    count = (n - nperseg // 2) // hop
    segs = np.lib.stride_tricks.sliding_window_view(y, nperseg, axis=-1)[..., ::hop, :][
        ..., :count, :
    ]
    segs = segs - np.mean(segs, axis=-1, keepdims=True)  # the "constant" detrend
    spec = sps_fft.rfft(segs * sft.win.conj(), n=sft.mfft, axis=-1)
    # power as (..., frequency, segment), the layout scipy averages over
    power = np.ascontiguousarray(np.swapaxes(spec.real**2 + spec.imag**2, -1, -2))
    power[..., 1 : -1 if sft.mfft % 2 == 0 else None, :] *= 2
    return sft.f, power.mean(axis=-1) if count > 1 else power[..., 0]


# ---------------------------------------------------------------------------- rules


def impact_rate(peaks: np.ndarray, n: int, period: float) -> float:
    """Impacts per forcing period: over the span from the first impact to the last when
    there are several (a count over the record's length is off by up to one impact at
    each edge, so two records of different lengths on the same orbit disagree: 0.985
    against 1.020 on 28 and 40 periods of a period-1 orbit), else the count over the record."""
    if peaks.size >= 3 and peaks[-1] > peaks[0]:
        return float((peaks.size - 1) / ((peaks[-1] - peaks[0]) / period))
    return float(peaks.size / (n / period))


def signal_statistics(
    accel: ArrayLike,
    fs_hz: float,
    natural_frequency_hz: float,
    frequency_ratio: float | None = None,
    inclination: bool = True,
) -> SignalStatistics:
    """All phase-independent statistics of one record (see the module notes).

    Parameters
    ----------
    accel : array_like
        The record (any gain and polarity), at least a few forcing periods long.
    fs_hz : float
        Sampling rate, Hz.
    natural_frequency_hz : float
        ``f_n`` of the oscillator (the time unit of every statistic).
    frequency_ratio : float, optional
        Forcing frequency over ``f_n``; default: from the dominant period.
    inclination : bool, optional
        Also run the geometric method for the inclination statistics (about
        20 ms per 6,000 samples).

    Returns
    -------
    SignalStatistics

    Raises
    ------
    SignalError
        If the record is too short or constant.
    """
    z, scale = robust_standardise(accel)
    pol = skew_polarity(z)
    y = pol * z
    p_n = fs_hz / natural_frequency_hz
    frequency_ratio = _checked_ratio(y, p_n, frequency_ratio)
    return _statistics(
        accel, z, scale, pol, y, lowpass(y, DETECTION_LOWPASS / p_n),
        lambda: highpass(y, fs_hz, RINGING_HIGHPASS * natural_frequency_hz),
        welch_log_psd(z, fs_hz, natural_frequency_hz),
        fs_hz, natural_frequency_hz, frequency_ratio, inclination,
    )  # fmt: skip


def batch_signal_statistics(
    records: Sequence[ArrayLike],
    fs_hz: Sequence[float],
    natural_frequency_hz: Sequence[float],
    frequency_ratio: Sequence[float],
    inclination: bool = True,
) -> list[SignalStatistics | None]:
    """:func:`signal_statistics` of many records (None where it raises :class:`SignalError`).

    The same numbers, faster: records of the same length, sampling rate and
    ``f_n`` are filtered and their Welch spectra taken as one 2-D array (a
    campaign's simulated batch has a few such groups; per record, the calls'
    overhead costs as much as the arithmetic).
    """
    n = len(records)
    out: list[SignalStatistics | None] = [None] * n
    prepared: dict[tuple[int, float, float], list[tuple[int, np.ndarray, float, int]]] = {}
    for i, (a, fs, fn) in enumerate(zip(records, fs_hz, natural_frequency_hz, strict=True)):
        try:
            z, scale = robust_standardise(a)
        except SignalError:
            continue
        prepared.setdefault((z.size, float(fs), float(fn)), []).append(
            (i, z, scale, skew_polarity(z))
        )
    for (_, fs, fn), group in prepared.items():
        z2 = np.vstack([z for _, z, _, _ in group])
        y2 = z2 * np.array([pol for _, _, _, pol in group], dtype=np.float64)[:, None]
        p_n = fs / fn
        smooth2 = lowpass(y2, DETECTION_LOWPASS / p_n)
        ring2 = highpass(y2, fs, RINGING_HIGHPASS * fn)
        psd_f, log_psd2 = welch_log_psd(z2, fs, fn)
        for j, (i, z, scale, pol) in enumerate(group):
            try:
                ratio = _checked_ratio(y2[j], p_n, frequency_ratio[i])
                out[i] = _statistics(
                    records[i], z, scale, pol, y2[j], smooth2[j], lambda r=ring2[j]: r,
                    (psd_f, log_psd2[j]), fs, fn, ratio, inclination,
                )  # fmt: skip
            except SignalError:
                out[i] = None
    return out


def _checked_ratio(y: np.ndarray, p_n: float, frequency_ratio: float | None) -> float:
    """The forcing frequency ratio (from the dominant period when None), checked against the
    record's length."""
    if frequency_ratio is None:
        from stiffnet.geometry.estimate import dominant_period

        frequency_ratio = p_n / dominant_period(y)
    p_f = p_n / frequency_ratio
    if y.size < 3 * p_f:
        raise SignalError(f"record too short: {y.size} samples, under three forcing periods")
    return float(frequency_ratio)


def _statistics(
    accel: ArrayLike,
    z: np.ndarray,
    scale: float,
    pol: int,
    y: np.ndarray,
    smooth: np.ndarray,
    ringing_copy: Callable[[], np.ndarray],
    spectrum: tuple[np.ndarray, np.ndarray],
    fs_hz: float,
    natural_frequency_hz: float,
    frequency_ratio: float,
    inclination: bool,
) -> SignalStatistics:
    """The rules of :func:`signal_statistics` on a standardised record and its filtered
    copies (``ringing_copy()``: the high-passed one, asked for only when there are spikes)."""
    p_n = fs_hz / natural_frequency_hz
    p_f = p_n / frequency_ratio
    peaks = spike_peaks(y, smooth, p_f)
    t, segs = aligned_segments(y, peaks, p_n)
    nan = float("nan")
    heights, widths = spike_heights_widths(t, segs)
    if segs.shape[0]:
        waveform = segs.mean(axis=0)
        repeat = impact_pattern(peaks, p_f)
        height = orbit_median(heights, repeat)
        width = orbit_median(widths, repeat) if np.isfinite(widths).any() else nan
    else:
        waveform, t = np.empty(0), np.empty(0)
        height = width = nan

    ring = ring_f = nan
    if peaks.size and np.isfinite(width):
        r = ringing_copy()
        start = max(0.05, 1.5 * width)
        post, pre = ringing_curves(r, peaks, p_n, start)
        if post.size and np.median(pre) > 0:
            ring = float(np.log10(np.median(post) / np.median(pre)))
        fr, spec = ringing_spectrum(r, peaks, p_n, start)
        if spec.size:
            ring_f = float(fr[int(np.argmax(spec))] * p_n)

    half = max(BRIDGE_MIN, BRIDGE_WIDTHS * width if np.isfinite(width) else BRIDGE_MIN) * p_n
    spans = spike_spans(y.size, refined_peaks(y, peaks), half)
    if y.size - sum(hi - lo for lo, hi in spans) < 2 * N_HARMONICS + 8:
        spans = []
    # on the low-passed copy: a sensor's ringing leaks into a least-squares fit on raw samples
    flight = bridged_free_flight(smooth, spans)
    amps = harmonic_amplitudes(flight, 1.0 / p_f, np.ones(y.size, dtype=bool), N_HARMONICS)
    harmonics = np.maximum(amps / max(amps[0], 1e-12), HARMONIC_FLOOR)
    harmonics[0] = 1.0

    psd_f, log_psd = spectrum
    stats = SignalStatistics(
        fs_hz=float(fs_hz),
        natural_frequency_hz=float(natural_frequency_hz),
        frequency_ratio=float(frequency_ratio),
        scale=scale,
        polarity=pol,
        impacts=peaks,
        waveform_t=t,
        waveform=waveform,
        spike_height=height,
        spike_width=width,
        ringing=ring,
        ringing_frequency=ring_f,
        harmonics=harmonics,
        psd_f=psd_f,
        log_psd=log_psd,
        impacts_per_period=impact_rate(peaks, y.size, p_f),
    )
    if inclination and peaks.size:
        # the estimate alone: the features built around it are not statistics here
        from stiffnet.features.inclination_features import window_geometry

        _, est = window_geometry(accel, fs_hz)
        if est is not None and est.contact_detected:
            stats.inclination_before_deg = float(est.inclination_before_deg)
            stats.inclination_after_deg = float(est.inclination_after_deg)
            stats.extra["geometric_beta"] = est.geometric_beta
    return stats
