"""The phase-independent statistics move continuously with the record.

A fit walks the model's parameters; a statistic counted in whole samples or grid
steps (a spike's width, a mask's edge, a window's start) steps as the record
changes smoothly, and the local search stalls on the plateaus between steps.
"""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.measurement.statistics import (
    WAVEFORM_RATE,
    free_flight_weights,
    refined_peaks,
    ringing_curves,
    signal_statistics,
    spike_heights_widths,
)

FS, FN = 1500.0, 9.48


def test_width_at_half_height_is_interpolated_between_grid_points():
    t = np.arange(-32, 65) / WAVEFORM_RATE
    for half_base in (0.0371, 0.05, 0.0613):  # triangles: the half-height width is half_base
        seg = np.maximum(0.0, 1.0 - np.abs(t) / half_base)
        height, width = spike_heights_widths(t, seg[None, :])
        assert height[0] == pytest.approx(1.0)
        assert width[0] == pytest.approx(half_base, abs=1e-12)


def test_free_flight_weights_open_a_hole_as_wide_as_the_half_width():
    n = 200
    for half in (10.0, 10.3, 10.7, 11.0):  # the hole grows with the half width, not in steps
        w = free_flight_weights(n, np.array([60.4, 140.0]), half, taper=3.0)
        assert np.sum(1.0 - w) == pytest.approx(2 * 2 * half)
        assert w[60] == 0.0 and w[100] == 1.0 and np.all((w >= 0) & (w <= 1))
    assert np.all(free_flight_weights(n, np.array([], dtype=float), 5.0) == 1.0)


def test_refined_peak_is_the_parabola_vertex():
    i = np.arange(40, dtype=float)
    y = -((i - 17.3) ** 2)
    assert refined_peaks(y, np.array([17]))[0] == pytest.approx(17.3)
    assert refined_peaks(y, np.array([0]))[0] == 0.0  # an edge stays where it is


def test_ringing_windows_weigh_the_samples_they_overlap():
    r = np.sqrt(np.arange(1000, dtype=float))  # r**2 is the sample index
    post, pre = ringing_curves(r, np.array([500]), 100.0, 0.1)  # 10 .. 35 samples away
    assert post[0] ** 2 == pytest.approx(500 + 22.5, abs=0.05)
    assert pre[0] ** 2 == pytest.approx(500 - 22.5, abs=0.05)
    ones = ringing_curves(np.ones(1000), np.array([500]), 100.0, 0.1234)
    assert ones[0][0] == pytest.approx(1.0) and ones[1][0] == pytest.approx(1.0)


def _spikes_on_a_sine(sigma: float) -> np.ndarray:
    t = np.arange(int(6 * FS)) / FS
    y = np.sin(2 * np.pi * FN * t) + 0.2 * np.sin(4 * np.pi * FN * t + 0.3)
    for c in (np.arange(60) + 0.37) / FN:
        y += 6.0 * np.exp(-0.5 * ((t - c) / sigma) ** 2)
    return y


def test_statistics_move_continuously_as_the_spikes_widen():
    """Gaussian spikes widened in 21 steps across 1.6 grid steps of width: the width reads
    the full width at half height, and width, free-flight harmonics and ringing change by
    small, even steps (counted in grid steps, the width jumped 1/128 natural period twice,
    harmonic_2 by 0.024 and 0.051, i.e. 0.8 and 1.7 tolerances, and the ringing by 0.06)."""
    sigmas = np.linspace(0.004, 0.005, 21)
    stats = [signal_statistics(_spikes_on_a_sine(s), FS, FN, 1.0, False) for s in sigmas]
    width = np.array([s.spike_width for s in stats])
    fwhm = 2 * np.sqrt(2 * np.log(2)) * sigmas * FN
    assert np.allclose(width, fwhm, rtol=0.07)
    dw = np.diff(width)
    assert np.all(dw > 0) and dw.max() < 1.2 * dw.min()
    assert np.abs(np.diff([s.harmonics[1] for s in stats])).max() < 0.003
    assert np.abs(np.diff([s.ringing for s in stats])).max() < 0.003
