"""Relative displacement and velocity of the mass from its absolute acceleration.

The accelerometer reads the absolute acceleration of the mass (docs/simulator.md,
eqs 11-12 of the paper): ``accel = x'' - b(t)`` with ``x`` the displacement
relative to the table and ``b`` the table's acceleration, a sinusoid at the
forcing frequency (plus the shaker's harmonics). Integrating the record twice in
the frequency domain therefore gives ``x`` up to the table's motion - unknown
sinusoids at the forcing harmonics - and a constant; both are fitted alongside
the free-flight law (:mod:`stiffnet.restoring_force.free_flight`).

Time is measured in forcing radians, ``tau = 2 pi f_f t``: the forcing is at
frequency 1 and the free-flight stiffness is ``(f_n / f_f)**2``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from stiffnet.errors import SignalError

#: Spectral lines below this fraction of the forcing frequency are dropped by the
#: integration: they hold drift and the integrated noise (amplified as 1 / w**2),
#: while an orbit of period up to three forcing periods has its lowest line at 1/3.
CUTOFF = 0.25
#: Bins on each side of a forcing harmonic kept by the integration of the forcing lines
#: alone (:func:`integrate_spectral`): the record spans whole periods only to the nearest
#: sample, and the line's main lobe spreads over its neighbours.
LINE_BINS = 1
#: The contact damping ratio from which the soft-contact joint fit is also read with its state
#: integrated from the forcing lines alone: an elastic contact's force has no step to alias,
#: and its fitted ratio scatters about 0 by a few hundredths.
ALIAS_MIN_DAMPING = 0.05


#: A velocity-spectrum line this strong against the top one is a rival forcing line (an
#: orbit of two impacts every three periods has lines at f and 4f/3 of nearly equal power).
RIVAL = 0.5


def forcing_candidates(
    a: np.ndarray, fs_hz: float, min_hz: float | None = None, rival: float = RIVAL
) -> list[float]:
    """Candidate forcing periods in samples, strongest first: the velocity spectrum's peak and
    its rivals.

    The top line is :func:`stiffnet.geometry.dominant_period`'s (velocity spectrum:
    the forcing line stays on top of the impact harmonics); with `min_hz` only
    lines above it are searched (a charge amplifier's start-up transient puts a
    low line on top, 1/f**2 weighted). Local maxima within `rival` of the top
    and more than 10 % away from it in frequency are returned too (at most two):
    on a period-n orbit the spectrum alone cannot tell the forcing line from a
    sub-harmonic multiple, the free-flight law can (:func:`restoring_force_estimate`).
    """
    a = np.asarray(a, dtype=np.float64)
    n = a.size
    spec = np.abs(np.fft.rfft((a - a.mean()) * np.hanning(n))) ** 2
    k = np.arange(spec.size, dtype=np.float64)
    lo = max(2, int(np.ceil(min_hz * n / fs_hz))) if min_hz else 2
    if lo >= spec.size - 2:
        raise SignalError("record too short to find a forcing line")
    vel = np.zeros_like(spec)
    vel[lo:-1] = spec[lo:-1] / k[lo:-1] ** 2
    if not np.any(vel > 0):
        raise SignalError("no oscillation found in the record")
    top = int(np.argmax(vel))
    peaks = np.flatnonzero((vel[1:-1] > vel[:-2]) & (vel[1:-1] >= vel[2:])) + 1
    peaks = peaks[(vel[peaks] >= rival * vel[top]) & (np.abs(peaks / top - 1) > 0.1)]
    rivals = [int(j) for j in peaks[np.argsort(vel[peaks])[::-1]][:2]]
    out = [float(n / top)]
    for j in rivals:
        if all(abs((n / j) / p - 1) > 0.1 for p in out):
            out.append(float(n / j))
    return out


def coarse_period(a: np.ndarray, fs_hz: float, min_hz: float | None = None) -> float:
    """Forcing period in samples: the strongest of :func:`forcing_candidates`."""
    return forcing_candidates(a, fs_hz, min_hz)[0]


def forcing_frequency(
    accel: ArrayLike,
    fs_hz: float,
    pad: int = 8,
    min_hz: float | None = None,
    coarse: float | None = None,
) -> float:
    """Forcing frequency of an impact-oscillator record in Hz: the velocity spectrum's peak.

    The coarse peak is :func:`stiffnet.geometry.dominant_period` (velocity
    spectrum: the forcing line stays on top of the impact harmonics and of the
    sub-harmonics of period-n orbits); it is refined within 10 % on a
    ``pad``-times zero-padded Hann periodogram of the acceleration itself (the
    velocity's ``1/f**2`` weight tilts the window's main lobe and moves the peak
    by ~0.5 %, a quarter radian of phase over 16 periods) by a parabola through
    the log power of the three bins around the peak.

    Parameters
    ----------
    accel : array_like
        Acceleration record (any gain and polarity).
    fs_hz : float
        Sampling rate, Hz.
    pad : int
        Zero-padding factor of the refining periodogram.
    min_hz : float, optional
        Lowest forcing frequency searched (the caller's bound from a known f_n).
    coarse : float, optional
        Coarse period in samples to refine (one of :func:`forcing_candidates`).

    Returns
    -------
    float
        Forcing frequency, Hz.
    """
    a = np.asarray(accel, dtype=np.float64)
    period = coarse_period(a, fs_hz, min_hz) if coarse is None else float(coarse)
    n = a.size
    m = int(2 ** np.ceil(np.log2(pad * n)))
    spec = np.abs(np.fft.rfft((a - a.mean()) * np.hanning(n), m)) ** 2
    # the acceleration's own line: a 1/f**2 weight would tilt the window's main lobe
    vel = spec
    centre = m / period
    lo, hi = max(2, int(centre * 0.9)), min(spec.size - 2, int(np.ceil(centre * 1.1)) + 1)
    j = lo + int(np.argmax(vel[lo:hi]))
    y0, y1, y2 = np.log(np.maximum(vel[j - 1 : j + 2], 1e-300 * max(vel[j], 1e-300)))
    den = y0 - 2 * y1 + y2
    shift = float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5)) if den < 0 else 0.0
    return float((j + shift) * fs_hz / m)


def periodic_length(accel: np.ndarray, period: float, tail: int | None = None) -> int:
    """Rule: the record length, a whole number of forcing periods, whose wrap-around fits best.

    The frequency-domain integration treats the segment as one period of a
    periodic signal; a period-n orbit (several impacts per period, or one impact
    every few periods) is periodic only over a multiple of n forcing periods.
    Among the last four whole-period lengths, the one whose next ``tail``
    samples best repeat the first ones is kept.

    Parameters
    ----------
    accel : numpy.ndarray
        Record.
    period : float
        Forcing period, samples.
    tail : int, optional
        Samples compared (default: a quarter period).

    Returns
    -------
    int
        Segment length in samples.
    """
    n = accel.size
    tail = max(4, int(0.25 * period)) if tail is None else tail
    whole = int((n - tail) // period)
    if whole < 1:
        return n
    best, best_err = int(round(whole * period)), np.inf
    tie = 1e-12 * float(np.mean(accel**2))  # relative: the record's unit must not decide
    for m in range(whole, max(0, whole - 4), -1):
        length = int(round(m * period))
        err = float(np.mean((accel[length : length + tail] - accel[:tail]) ** 2))
        if err < best_err - tie:
            best, best_err = length, err
    return best


def integrate_spectral(
    accel: np.ndarray, dtau: float, cutoff: float = CUTOFF, forcing_lines_only: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and displacement from acceleration by division by ``i w`` and ``-w**2``.

    With `forcing_lines_only`, only the bins within :data:`LINE_BINS` of a forcing harmonic
    are integrated: the state of a period-1 orbit whose record carries the aliases of a
    force step. A damped contact's force jumps to ``c_c v`` at its onset; sampled with no
    anti-alias filter ahead of the sampler (a simulator's record, or a digital chain after
    it), the step's harmonics above Nyquist fold back, and where the samples per forcing
    period are not a whole number they fold between the forcing lines, down to a third of
    the forcing frequency, where the division by ``w**2`` makes them a displacement that
    no motion of the mass has (stiffnet's engine, beta 5.5, zeta_c 0.2, noise-free, at 83.3
    samples per period: the joint fit reads 3.79; at 80 or 100 samples per period, or
    behind an anti-alias filter, 5.42-6.03; docs/crosscheck.md).

    Parameters
    ----------
    accel : numpy.ndarray
        Acceleration segment, treated as one period of a periodic signal.
    dtau : float
        Sampling step in forcing radians (``2 pi f_f / fs``).
    cutoff : float
        Lines below ``cutoff`` (forcing frequencies) are set to zero.

    Returns
    -------
    velocity, displacement : numpy.ndarray
        Zero-mean integrals, same length as `accel`.
    """
    n = accel.size
    spec = np.fft.rfft(accel - accel.mean())
    w = 2 * np.pi * np.fft.rfftfreq(n, dtau)
    keep = w >= cutoff
    if forcing_lines_only:  # w is in forcing harmonics; one bin is 2 pi / (n dtau) of it
        keep &= np.abs(w - np.rint(w)) * n * dtau / (2 * np.pi) <= LINE_BINS + 0.5
    iw = np.zeros_like(spec)
    iw[keep] = 1.0 / (1j * w[keep])
    vel = np.fft.irfft(spec * iw, n)
    disp = np.fft.irfft(spec * iw * iw, n)
    return vel, disp


def check_record(accel: ArrayLike, period: float, min_periods: float) -> np.ndarray:
    """The record as float64, or SignalError if it holds fewer than `min_periods` periods."""
    a = np.asarray(accel, dtype=np.float64)
    if a.size < min_periods * period:
        raise SignalError(
            f"record too short for the restoring-force estimate: {a.size / period:.1f} forcing "
            f"periods, at least {min_periods:g} needed"
        )
    return a
