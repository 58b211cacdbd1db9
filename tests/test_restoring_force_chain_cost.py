"""What the sensor chain's fit costs, and that its cheaper paths compute the same thing.

The chain fit designs a filter stage per residual evaluation and differences its residuals
for the Jacobian; both are done without scipy's general machinery, and must give scipy's
bits (the fits, and so every map read through a fitted chain, are unchanged). The
restoring-force estimate without an interval (what the contact-law discovery reads) must
give the same map and the same chain as with one.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal
from scipy.optimize._numdiff import approx_derivative

from stiffnet.restoring_force import restoring_force_estimate
from stiffnet.restoring_force.chain import (
    OVERSAMPLE,
    SensorChain,
    _bounds,
    _difference_jacobian,
    _lowpass_stage,
    _n_shape,
    _residuals,
    _resonance_stage,
    _theta,
    _Windows,
    chain_sos,
    contact_pulse,
)
from tests.independent_rig import RigRun, record

FN = 9.48


def test_stage_designs_are_scipys_bit_for_bit():
    """The resonance's and the second-order low-pass's sections: scipy's zpk2sos of the
    bilinear transform and scipy's butter, bit for bit, over the rates and bands fits visit."""
    rng = np.random.default_rng(0)
    for _ in range(3000):
        fs = float(rng.choice([500.0, 2000.0, 16000.0, 64000.0]) * rng.uniform(0.5, 2.0))
        hz = float(rng.uniform(1e-3, 0.499) * fs)
        zeta = float(np.exp(rng.uniform(np.log(0.005), np.log(0.9))))
        w = 2.0 * fs * np.tan(np.pi * hz / fs)
        poles = np.roots([1.0, 2.0 * zeta * w, w * w])
        scipy_res = signal.zpk2sos(*signal.bilinear_zpk([], poles, w * w, fs))
        assert np.array_equal(_resonance_stage.__wrapped__(hz, zeta, fs), scipy_res)
        scipy_lp = signal.butter(2, hz, fs=fs, output="sos")
        assert np.array_equal(_lowpass_stage.__wrapped__(2, hz, fs), scipy_lp)
    # other orders and an overdamped resonance stay scipy's own design
    assert np.array_equal(_lowpass_stage.__wrapped__(3, 300.0, 2000.0),
                          signal.butter(3, 300.0, fs=2000.0, output="sos"))  # fmt: skip
    assert _resonance_stage.__wrapped__(300.0, 1.5, 2000.0).shape == (1, 6)


def _windows(n: int = 6, length: int = 60, fs: float = 2000.0) -> _Windows:
    """Residual force of ``n`` 50 Hz contacts through a 2nd-order 100 Hz low-pass at
    sub-sample onsets, with noise: the windows a chain fit reads."""
    fine = fs * OVERSAMPLE
    pulse = contact_pulse(np.arange((length + 2) * OVERSAMPLE) / fine, 50.0, 0.05, 0.0, FN)
    pulse = signal.sosfilt(chain_sos(SensorChain(lowpass_hz=100.0, lowpass_order=2), fine), pulse)
    onsets = 6.0 + np.linspace(0.1, 0.9, n)
    pos = (np.arange(length)[None, :] - onsets[:, None]) * OVERSAMPLE
    r = np.interp(pos, np.arange(pulse.size), pulse, left=0.0, right=pulse[-1])
    r = r + 0.5 * np.random.default_rng(1).standard_normal(r.shape)
    win = _Windows(r, np.arange(n) * 200, np.full(n, 10.0), 8)
    win.free_hz = FN
    return win


@pytest.mark.parametrize("structure", [(False, 0), (True, 0), (False, 2), (True, 3)])
def test_chain_fit_jacobian_is_scipys_sparse_differences(structure):
    """The fit's Jacobian is the matrix scipy's ``least_squares`` differences from the
    sparsity pattern (same steps, reversed or shortened at a bound; same storage), at
    random points, at a point against an upper bound and at a zero parameter."""
    win, fs = _windows(), 2000.0
    lo, hi = _bounds(win, fs, FN, structure)
    k = _n_shape(structure)
    pattern = np.zeros((win.r.size, k + win.n), dtype=int)
    pattern[:, :k] = 1
    pattern[np.arange(win.r.size), k + np.repeat(np.arange(win.n), win.length)] = 1
    rng = np.random.default_rng(2)
    start = _theta(structure, (60.0, 0.1, 0.0), (300.0, 0.05), 120.0, np.full(win.n, 7.5))
    points = [np.clip(start, lo + 1e-9, hi - 1e-9)]
    points += [lo + (hi - lo) * rng.uniform(0.01, 0.99, lo.size) for _ in range(3)]
    points[1][0] = hi[0] - 1e-7  # the step must turn back
    points[2][2] = 0.0  # a relative step of zero falls back to sqrt(eps)

    def resid(x):
        return _residuals(x, win, fs, structure)

    for x in points:
        f0 = resid(x)
        ours = _difference_jacobian(resid, x, f0, k, win, lo, hi)
        theirs = approx_derivative(resid, x, method="2-point", rel_step=1e-4, f0=f0,
                                   bounds=(lo, hi), sparsity=pattern).tocsr()  # fmt: skip
        assert np.array_equal(ours.indptr, theirs.indptr)
        assert np.array_equal(ours.indices, theirs.indices)
        assert np.array_equal(ours.data, theirs.data)
        assert np.any(ours.data != 0)


@pytest.mark.slow
def test_an_estimate_without_interval_reads_the_same_map_and_chain():
    """Independent rig, beta 30 behind a 2nd-order 80 Hz low-pass, its chain always fitted:
    the estimate without an interval has the same map, contact law, beta and chain (less the
    low-passes profiled for the interval) as with one, and no interval."""
    run = RigRun(recording="r.csv", beta=30.0, fs_hz=2000.0, duration_s=3.5,
                 sensor={"lowpass_hz": 80.0, "lowpass_order": 2, "oversample": 8})  # fmt: skip
    accel = record(run, seed=3)[1]
    opts = dict(
        natural_frequency_hz=FN,
        forcing_frequency_hz=run.forcing_frequency_hz,
        max_periods=24.0,
        profile_highpass_below_r2=-np.inf,
    )
    full = restoring_force_estimate(accel, 2000.0, **opts)
    lean = restoring_force_estimate(accel, 2000.0, interval=False, **opts)
    assert full.sensor is not None and full.sensor.source == "fitted" and full.sensor.has_dynamics
    assert lean.sensor == full.sensor.__class__(**{**full.sensor.__dict__,
                                                   "lowpass_not_excluded": ()})  # fmt: skip
    for name in ("displacement", "velocity", "force"):
        assert np.array_equal(getattr(lean, name), getattr(full, name))
    assert lean.law == full.law and lean.beta == full.beta == pytest.approx(30.0, rel=0.2)
    assert np.all(np.isnan(lean.beta_interval))
    lo, hi = full.beta_interval
    assert lo < full.beta < hi
    # asked to profile the chain's unexcluded low-passes, the chain is the whole estimate's
    profiled = restoring_force_estimate(accel, 2000.0, interval=False, chain_profile=True, **opts)
    assert profiled.sensor == full.sensor and profiled.law == full.law


def test_behind_a_known_chain_the_recorded_maps_contact_law_is_not_fitted(monkeypatch):
    """Independent rig, beta 30 behind a 120 Hz order-4 low-pass and a 4 Hz high-pass, read
    through its data sheet (the campaign's pooled chain, the corner's interval given): the
    record as recorded gives the inverse only its free flight, so its contact law is not
    fitted (fewer contact-law fits), and the result, interval and every map included, is the
    one that fits it."""
    from stiffnet.restoring_force import contact_law, estimate

    sensor = {"lowpass_hz": 120.0, "lowpass_order": 4, "highpass_hz": 4.0}
    run = RigRun(recording="r.csv", beta=30.0, fs_hz=1250.0, duration_s=3.0, gap_mm=1.5,
                 sensor=sensor)  # fmt: skip
    accel = record(run, seed=1)[1]
    sheet = {**sensor, "lowpass_order": 4.0, "highpass_low_hz": 3.5, "highpass_high_hz": 4.4}
    fits = [0]
    real_fit, real_map = contact_law.fit_contact_law, estimate._fit_map

    def counted(*args, **kwargs):
        fits[0] += 1
        return real_fit(*args, **kwargs)

    def with_law(*args, contact=True, **kwargs):  # the map as read before: law always fitted
        return real_map(*args, **kwargs)

    monkeypatch.setattr(estimate, "fit_contact_law", counted)
    opts = dict(natural_frequency_hz=FN, sensor=sheet, sensor_fitted=True, max_periods=24.0)
    lean = restoring_force_estimate(accel, 1250.0, **opts)
    n_lean, fits[0] = fits[0], 0
    monkeypatch.setattr(estimate, "_fit_map", with_law)
    full = restoring_force_estimate(accel, 1250.0, **opts)
    assert fits[0] > n_lean
    assert lean.ok and lean.sensor.source == "data sheet" and lean.sensor.has_dynamics
    assert lean.to_dict() == full.to_dict()
    for name in ("displacement", "velocity", "force"):
        assert np.array_equal(getattr(lean, name), getattr(full, name))
    assert lean.beta == pytest.approx(30.0, rel=0.2)
