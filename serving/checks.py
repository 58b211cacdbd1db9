"""The predictor's first step: is this recording something the models can read?

Finite 1-D samples, ``fs > 0``, a known natural frequency ``f_n``;
``fs >= MIN_SAMPLES_PER_PERIOD * f_n`` (the lowest rate of the training data:
slower recordings do not resolve the impact spikes the models and the
geometric method read); at least one window; not constant. A clipped signal
(samples piled up at the extremes) and rates above the training range only add
warnings. Every refusal is one :class:`~stiffnet.errors.StiffnetError` line
that names the recording and the problem.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from stiffnet.errors import StiffnetError
from stiffnet.inputs import rate_ratio

#: Minimum sampling rate in samples per natural period: the training data's lowest rate.
MIN_SAMPLES_PER_PERIOD = 50.0
#: Rates above this many samples per natural period are beyond the training data (warning).
MAX_TRAINED_SAMPLES_PER_PERIOD = 500.0
#: A signal is reported as clipped when this fraction of samples (and >= 3) sits at an extreme.
CLIP_FRACTION = 1e-3


def clipping_warning(a: np.ndarray) -> str | None:
    """A warning if many samples sit exactly at the maximum or minimum (a saturated sensor)."""
    n = a.size
    need = max(3, int(CLIP_FRACTION * n))
    parts = []
    for name, value in (("maximum", a.max()), ("minimum", a.min())):
        count = int(np.count_nonzero(a == value))
        if count >= need:
            parts.append(f"{count} samples at the {name} {value:.6g}")
    if not parts:
        return None
    return f"signal looks clipped ({', '.join(parts)}): impacts may be flattened"


#: A sensor holding one value this many natural periods or longer has dropped out (a loose
#: cable, a logger's gap filled with zeros): the mass of a driven rig never rests that long,
#: and the noise alone moves the last digit from one sample to the next.
DROPOUT_PERIODS = 1.0


def dropout_samples(fs: float, fn: float) -> int:
    """The shortest run of one repeated value that is a dropout, in samples (at least 4)."""
    return max(4, int(math.ceil(DROPOUT_PERIODS * fs / fn)))


def held_runs(a: np.ndarray, min_samples: int) -> list[tuple[int, int]]:
    """``(start, stop)`` sample indices of each run of one repeated value in ``a`` at least
    ``min_samples`` long, in order."""
    a = np.asarray(a).reshape(-1)
    if a.size < min_samples:
        return []
    bounds = np.concatenate(([0], np.flatnonzero(a[1:] != a[:-1]) + 1, [a.size]))
    long = np.flatnonzero(np.diff(bounds) >= min_samples)
    return [(int(bounds[i]), int(bounds[i + 1])) for i in long]


def dropout_words(runs: list[tuple[int, int]], fs: float, value: float) -> str:
    """``runs`` (sample indices) of a held value described in one clause, times in s."""
    total = sum(stop - start for start, stop in runs)
    shown = ", ".join(f"{start / fs:.2f}-{stop / fs:.2f} s" for start, stop in runs[:3])
    more = f" and {len(runs) - 3} more" if len(runs) > 3 else ""
    return (
        f"the signal holds one value ({value:.6g}) for {total / fs:.3g} s in {len(runs)} run(s) "
        f"of a natural period or longer ({shown}{more}): a dropout (a loose cable, a logger's "
        "gap filled in), not the rig's motion"
    )


def dropout_warning(a: np.ndarray, fs: float, fn: float) -> str | None:
    """A warning if the record holds one value for a natural period or longer (a dropout),
    which the windows covering it read as if it were the rig's motion."""
    runs = held_runs(a, dropout_samples(fs, fn))
    if not runs:
        return None
    return f"{dropout_words(runs, fs, float(a[runs[0][0]]))}: the estimate reads it as signal"


def finite_samples(accel: Any, what: str) -> np.ndarray:
    """The samples as a finite 1-D float64 array of at least 2 samples."""
    try:
        a = np.asarray(accel, dtype=np.float64)
    except (TypeError, ValueError):
        raise StiffnetError(f"{what}: samples are not numbers") from None
    if a.ndim != 1:
        raise StiffnetError(f"{what}: expected 1-D samples, got shape {a.shape}")
    if a.size < 2:
        state = "is empty" if a.size == 0 else "has only one sample"
        raise StiffnetError(f"{what}: recording {state} (need at least 2 samples)")
    bad = ~np.isfinite(a)
    if bad.any():
        raise StiffnetError(
            f"{what}: {int(bad.sum())} NaN/inf samples (first at sample {int(np.argmax(bad))})"
        )
    return a


def rate_warnings(fs: float, fn: float, what: str) -> list[str]:
    """Refuse a rate below the training data's; a warning for one above it."""
    ratio = fs / fn
    if ratio < MIN_SAMPLES_PER_PERIOD:  # first: its message names a unit mistake
        from stiffnet.inputs import where_given
        from stiffnet.recordings import unit_mistake_hint

        hint = unit_mistake_hint(
            fs, MIN_SAMPLES_PER_PERIOD * fn, 4 * MAX_TRAINED_SAMPLES_PER_PERIOD * fn
        )
        # the rate is only low against f_n: a mistyped f_n (2500 for 25) reads the same, and
        # a time unit already given makes the unit story wrong, so both are named
        fn_given = where_given("--fn", "the manifest's column natural_frequency_hz",
                               "the field natural_frequency_hz")  # fmt: skip
        raise StiffnetError(
            f"{what}: sampling rate {fs:.6g} Hz is below the minimum "
            f"{MIN_SAMPLES_PER_PERIOD * fn:.6g} Hz ({MIN_SAMPLES_PER_PERIOD:g} x the natural "
            f"frequency {fn:.6g} Hz){hint}; if the natural frequency is not {fn:.6g} Hz, give "
            f"it ({fn_given}: this rate reads one up to {fs / MIN_SAMPLES_PER_PERIOD:.3g} Hz)"
        )
    rate_ratio(fs, fn, what)  # the physical upper bound
    if ratio > MAX_TRAINED_SAMPLES_PER_PERIOD:
        return [
            f"sampling rate is {ratio:.3g} x the natural frequency, above the training data's "
            f"{MAX_TRAINED_SAMPLES_PER_PERIOD:g} x"
        ]
    return []


def checked_recording(
    accel: Any, fs: float, fn: float, window_periods: float, what: str
) -> tuple[np.ndarray, list[str]]:
    """The checked, scaled samples and the warnings (see the module notes).

    The samples are scaled by a power of two so that the peak lies in [0.5, 1):
    exact in floating point (the results do not change), and std/mean cannot
    overflow for 1e300 inputs.

    Parameters
    ----------
    accel : array_like
        The recording's samples.
    fs, fn : float
        Sampling rate and natural frequency in Hz (already range-checked).
    window_periods : float
        Natural periods per model window (the recording must hold one).
    what : str
        The recording's name for messages.

    Raises
    ------
    StiffnetError
        Unusable input, with a one-line message.
    """
    a = finite_samples(accel, what)
    warnings = rate_warnings(fs, fn, what)
    # before the scaling below: the values as recorded
    clip, dropout = clipping_warning(a), dropout_warning(a, fs, fn)
    peak = float(np.max(np.abs(a)))
    if peak > 0:
        a = np.ldexp(a, -int(np.frexp(peak)[1]))
    if not a.std() > 0:
        raise StiffnetError(f"{what}: recording is constant (no signal)")
    need = window_periods * fs / fn  # samples in one window
    if not (math.isfinite(need) and a.size >= round(need)):
        raise StiffnetError(
            f"{what}: recording is too short ({a.size / fs:.3g} s): one window of "
            f"{window_periods:g} natural periods needs {need / fs:.3g} s "
            f"({round(need) if need < 1e15 else f'{need:.3g}'} samples at {fs:.6g} Hz)"
        )
    if clip:
        warnings.append(clip)
    if dropout:
        warnings.append(dropout)
    return a, warnings
