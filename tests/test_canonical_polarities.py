"""The batched polarity rule of the CNN's canonical window equals the per-row rule exactly."""

from pathlib import Path

import numpy as np
import pytest

from stiffnet.features.windows import (
    _first_medians,
    _polarities_per_row,
    _rows_peaks,
    _smoothed_indicator,
    canonical_polarities,
    window_length,
    window_starts,
)
from stiffnet.recordings import read_recording

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "recordings"


def _standardised(w: np.ndarray) -> np.ndarray:
    return (w - w.mean(axis=1, keepdims=True)) / w.std(axis=1, keepdims=True)


def _spiky_windows(rng, rows: int, n: int, period: float, kind: str) -> np.ndarray:
    """Forced response plus impact spikes of either sign, noise of several kinds."""
    t = np.arange(n)
    out = np.empty((rows, n))
    for i in range(rows):
        x = rng.uniform(0.2, 2) * np.sin(2 * np.pi * t / (period * rng.uniform(0.9, 1.2)))
        hits = rng.choice(n, size=rng.integers(0, max(1, int(2 * n / period))), replace=False)
        x[hits] += rng.choice([-1, 1]) * rng.uniform(2, 12, hits.size)
        x[np.clip(hits + 1, 0, n - 1)] += 0.5 * x[hits]  # a spike of two samples
        if kind == "heavy":
            x += 0.3 * rng.standard_t(2, n)
        elif kind == "quantised":  # equal samples: plateaus and tied peak heights
            x = np.round(x * 2 + 0.1 * rng.standard_normal(n)) / 2
        elif kind == "clipped":
            x = np.clip(x + 0.1 * rng.standard_normal(n), -1.5, 1.5)
        else:
            x += rng.uniform(0.01, 0.5) * rng.standard_normal(n)
        if x.std() == 0:
            x[0] += 1.0
        out[i] = x
    return _standardised(out)


@pytest.mark.parametrize("kind", ["gaussian", "heavy", "quantised", "clipped"])
@pytest.mark.parametrize(("n", "period"), [(3376, 211.0), (512, 32.0), (40, 10.0), (64, 300.0)])
def test_batched_polarities_equal_the_per_row_rule_on_random_windows(kind, n, period):
    seed = ["gaussian", "heavy", "quantised", "clipped"].index(kind) * 10_000 + n
    rng = np.random.default_rng(seed)
    a = _spiky_windows(rng, 60, n, period, kind)
    want = _polarities_per_row(a, period)
    got = canonical_polarities(a, period)
    np.testing.assert_array_equal(got, want)
    assert set(np.unique(got)) <= {-1.0, 1.0}


def test_batched_polarities_equal_the_per_row_rule_on_simulated_recordings():
    """The shipped simulator recordings, cut as the predictor cuts them, both signs."""
    for csv in sorted(EXAMPLES.glob("impact_beta*.csv")):
        rec = read_recording(csv)
        for fn in (9.48, 7.3, 12.1):
            n = window_length(rec.fs_hz, fn)
            starts = window_starts(rec.accel.size, n, max(1, n // 7))
            w = _standardised(rec.accel[starts[:, None] + np.arange(n)])
            w = np.concatenate([w, -w])
            period = rec.fs_hz / fn
            got = canonical_polarities(w, period)
            np.testing.assert_array_equal(got, _polarities_per_row(w, period))
            half = len(got) // 2
            np.testing.assert_array_equal(got[:half], -got[half:])  # a flip flips the sign


def test_tied_peak_heights_take_the_per_row_rule():
    """Quantised windows have tied candidates: those rows are named (and recomputed)."""
    rng = np.random.default_rng(3)
    a = _spiky_windows(rng, 40, 512, 32.0, "quantised")
    _, ind, thr, sep = _smoothed_indicator(a, 32.0)
    _, _, tied = _rows_peaks(ind, thr, sep)
    assert tied.size > 0
    np.testing.assert_array_equal(canonical_polarities(a, 32.0), _polarities_per_row(a, 32.0))


def test_rows_peaks_equal_find_peaks_row_by_row():
    from scipy.signal import find_peaks

    rng = np.random.default_rng(5)
    a = _spiky_windows(rng, 30, 700, 50.0, "gaussian")
    _, ind, thr, sep = _smoothed_indicator(a, 50.0)
    row, pos, _ = _rows_peaks(ind, thr, sep)
    for i in range(len(a)):
        want, _ = find_peaks(ind[i], height=float(thr[i]), distance=sep)
        np.testing.assert_array_equal(pos[row == i], want)


def test_first_medians_are_numpys_medians_to_the_last_bit():
    rng = np.random.default_rng(7)
    x = rng.standard_normal((200, 9)) * 10.0 ** rng.integers(-3, 4, (200, 1))
    count = rng.integers(1, 10, 200)
    want = np.array([np.median(x[i, : count[i]]) for i in range(200)])
    np.testing.assert_array_equal(_first_medians(x, count), want)
