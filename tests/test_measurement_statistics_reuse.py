"""The statistics' kept designs and batched transforms give the numbers of the plain
computation: bit for bit scipy's Welch segment by segment and a bridge drawn span by span;
the harmonics' kept least-squares operator (a pseudo-inverse, one product per record) those
of ``numpy.linalg.lstsq`` on a design built at every call, to rounding (1e-14 relative on a
24-recording simulated batch); and a batch's statistics those of each record alone."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as sps

from stiffnet.measurement import statistics as st


def _bridged_span_by_span(y: np.ndarray, spans) -> np.ndarray:
    out = np.array(y, dtype=np.float64, copy=True)
    for lo, hi in spans:
        i = np.arange(int(np.floor(lo)) + 1, int(np.ceil(hi)))
        if i.size == 0:
            continue
        a, b = (float(y[j] + (x - j) * (y[j + 1] - y[j]))
                for x, j in ((lo, min(int(np.floor(lo)), y.size - 2)),
                             (hi, min(int(np.floor(hi)), y.size - 2))))  # fmt: skip
        out[i] = a + (b - a) * (i - lo) / (hi - lo)
    return out


def _harmonics_built_each_call(y, f, mask, n_harmonics):
    t = np.flatnonzero(mask).astype(np.float64)
    cols = [np.ones_like(t)]
    for k in range(1, n_harmonics + 1):
        ph = 2 * np.pi * k * f * t
        cols += [np.cos(ph), np.sin(ph)]
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), y[mask], rcond=None)
    return np.hypot(coef[1::2], coef[2::2])


@pytest.mark.parametrize("n, fs, rows", [(12000, 2000.0, 1), (9000, 1500.0, 5), (6001, 1000.0, 3),
                                         (845, 2000.0, 2), (600, 2000.0, 1)])  # fmt: skip
def test_batched_welch_is_scipys_welch(n, fs, rows):
    rng = np.random.default_rng(n)
    y = rng.standard_normal((rows, n)) + np.sin(2 * np.pi * 9.9 * np.arange(n) / fs)
    y = y[0] if rows == 1 else y
    nper = int(min(n, max(16, round(st.WELCH_PERIODS * fs / 9.48))))  # 600: one segment
    f, p = st._welch(y, fs, nper)
    f_ref, p_ref = sps.welch(y, fs=fs, nperseg=nper, axis=-1)
    assert np.array_equal(f, f_ref) and p.shape == p_ref.shape
    assert np.array_equal(p, p_ref)


def test_a_bridge_drawn_at_once_is_the_span_by_span_one():
    rng = np.random.default_rng(1)
    y = np.cumsum(rng.standard_normal(5000))
    centres = np.sort(rng.uniform(-20, 5020, 60))
    for half in (0.4, 3.7, 41.3):  # spans inside one sample, short, merged
        spans = st.spike_spans(y.size, centres, half)
        assert np.array_equal(st.bridged_free_flight(y, spans), _bridged_span_by_span(y, spans))
    assert np.array_equal(st.bridged_free_flight(y, []), y)


def test_a_kept_harmonic_design_gives_the_same_amplitudes():
    rng = np.random.default_rng(2)
    n = 7000
    t = np.arange(n)
    y = np.sin(2 * np.pi * t / 205.3) + 0.1 * np.cos(4 * np.pi * t / 205.3) + rng.normal(0, 0.3, n)
    full = np.ones(n, dtype=bool)
    for _ in range(2):  # built, then kept: the pseudo-inverse's product, lstsq's to rounding
        got = st.harmonic_amplitudes(y, 1 / 205.3, full, 3)
        np.testing.assert_allclose(
            got, _harmonics_built_each_call(y, 1 / 205.3, full, 3), rtol=1e-12, atol=0
        )
    part = rng.uniform(size=n) > 0.3
    assert np.array_equal(st.harmonic_amplitudes(y, 1 / 205.3, part, 3),
                          _harmonics_built_each_call(y, 1 / 205.3, part, 3))  # fmt: skip
    assert got[1] / got[0] == pytest.approx(0.1, abs=0.01)


def test_a_records_statistics_are_those_of_the_plain_computation(monkeypatch):
    """A record with impacts (its batch of three): every statistic as with scipy's Welch, the
    design built per call and the bridge span by span (bit for bit, but the harmonics: to
    rounding, the kept pseudo-inverse against lstsq)."""
    from stiffnet.simulator.batch import OscillatorBatch
    from stiffnet.simulator.simulator import Simulator

    three = np.full(3, 1.0)
    batch = OscillatorBatch(beta=np.array([10.0, 30.0, 60.0]), gap=three, amplitude=three,
                            omega=1.05 * three, damping=0.02 * three,
                            natural_frequency_hz=9.48 * three)  # fmt: skip
    res = Simulator([]).simulate(
        batch, 1500.0 / 9.48, 6000, noise=0.02, rng=np.random.default_rng(0)
    )
    recs = list(res.accel)
    fast = st.batch_signal_statistics(recs, [1500.0] * 3, [9.48] * 3, [1.05] * 3, False)
    monkeypatch.setattr(
        st, "_welch", lambda y, fs, nper: sps.welch(y, fs=fs, nperseg=nper, axis=-1)
    )
    monkeypatch.setattr(st, "bridged_free_flight", _bridged_span_by_span)
    monkeypatch.setattr(st, "harmonic_amplitudes", _harmonics_built_each_call)
    plain = st.batch_signal_statistics(recs, [1500.0] * 3, [9.48] * 3, [1.05] * 3, False)
    assert all(s.has_impacts for s in fast)
    for a, b in zip(fast, plain, strict=True):
        for key, value in vars(a).items():
            other = vars(b)[key]
            if key == "harmonics":
                np.testing.assert_allclose(value, other, rtol=1e-12, atol=0, err_msg=key)
            elif isinstance(value, np.ndarray):
                assert np.array_equal(value, other, equal_nan=True), key
            elif isinstance(value, float) and np.isnan(value):
                assert np.isnan(other), key
            else:
                assert value == other, key


def _assert_same_statistics(a: st.SignalStatistics, b: st.SignalStatistics) -> None:
    """Every field of two records' statistics equal to floating-point rounding."""
    for key, value in vars(a).items():
        other = vars(b)[key]
        if isinstance(value, np.ndarray):
            assert value.shape == other.shape, key
            np.testing.assert_allclose(value, other, rtol=1e-9, atol=1e-12, err_msg=key)
        elif isinstance(value, float):
            np.testing.assert_allclose(value, other, rtol=1e-9, atol=1e-12, err_msg=key)
        else:
            assert value == other, key


def test_a_batchs_statistics_are_each_records_own():
    """A simulated batch of mixed lengths and rates (grouped by both for the filters and the
    Welch spectra, 2-D) gives every record the statistics :func:`signal_statistics` gives it
    alone, to rounding; a constant record is None in the batch, as alone it raises."""
    from stiffnet.errors import SignalError
    from stiffnet.simulator.batch import OscillatorBatch
    from stiffnet.simulator.simulator import Simulator

    four = np.full(4, 1.0)
    batch = OscillatorBatch(beta=np.array([10.0, 30.0, 60.0, 45.0]), gap=four, amplitude=four,
                            omega=np.array([1.05, 0.95, 1.05, 1.0]), damping=0.02 * four,
                            natural_frequency_hz=9.48 * four)  # fmt: skip
    res = Simulator([]).simulate(batch, 1500.0 / 9.48, 6000, noise=0.02,
                                 rng=np.random.default_rng(3))  # fmt: skip
    recs = [res.accel[0], res.accel[1], res.accel[2][:4500], res.accel[3][::2], np.ones(600)]
    fs = [1500.0, 1500.0, 1500.0, 750.0, 1500.0]
    ratio = [1.05, 0.95, 1.05, 1.0, 1.0]
    batched = st.batch_signal_statistics(recs, fs, [9.48] * 5, ratio, inclination=True)
    for rec, f, r, got in zip(recs[:4], fs, ratio, batched, strict=False):
        alone = st.signal_statistics(rec, f, 9.48, r, inclination=True)
        assert alone.has_impacts and np.isfinite(alone.inclination_before_deg)
        _assert_same_statistics(got, alone)
    assert batched[4] is None
    with pytest.raises(SignalError):
        st.signal_statistics(recs[4], 1500.0, 9.48, 1.0)
