"""The diagnosis' shortcuts give what the long way gives.

* The sensor chain's filter designs are kept per parameters: a filtered signal is bitwise
  the one a fresh design (scipy's ``butter``/``zpk2sos``/``sosfilt_zi``) gives.
* A numerical-engine effect's design, when its best point is scored again anyway, screens
  with a shorter transient (``fitting.SCREEN_SETTLE_TOLERANCE``) begun warm by the closed
  form (``fitting.SCREEN_WARM_START``): the point kept and every number reported are those
  of a cold screen at the fits' own transient.
"""

from __future__ import annotations

import numpy as np
import scipy.signal as sps

from stiffnet.campaign import ManifestRow
from stiffnet.campaign.simulate import FIT_SETTINGS, FIT_SETTINGS_NUMERICAL, simulate_rows
from stiffnet.effects.sensor_dynamics import SensorDynamics, resonance_sos
from stiffnet.measurement import fitting
from stiffnet.measurement.fitting import fit_effect, screen_settings
from stiffnet.measurement.statistics import signal_statistics
from stiffnet.measurement.target import CampaignTarget

ROW = ManifestRow(
    recording="r.csv",
    fs_hz=1250,
    natural_frequency_hz=9.48,
    frequency_ratio=1.0,
    amplitude=1.2,
    gap=1.2,
    damping_ratio=0.02,
    beta=30,
    noise=0.02,
)


def _fresh_chain(x: np.ndarray, fs: float, f_r: float, zeta: float, f_h: float) -> np.ndarray:
    """The chain of SensorDynamics.apply designed from scratch (no kept design)."""
    sos = np.vstack(
        [resonance_sos(f_r, zeta, fs), sps.butter(1, f_h, "highpass", fs=fs, output="sos")]
    )
    zi = sps.sosfilt_zi(sos)[:, None, :] * x[:, 0][None, :, None]
    return sps.sosfilt(sos, x, axis=-1, zi=zi)[0]


def test_kept_sensor_designs_filter_bitwise_like_fresh_ones():
    rng = np.random.default_rng(4)
    x = rng.standard_normal((3, 4000))
    fs = np.array([2000.0, 2000.0, 1250.0])
    eff = SensorDynamics(resonance_hz=237.0, resonance_damping=0.03, highpass_hz=1.0, lowpass_hz=0)
    p = eff.batch_params(3, rng)
    for _ in range(2):  # the second call is served by the kept designs
        out = eff.apply(x, fs, p, rng)
        for i in range(3):
            np.testing.assert_array_equal(
                out[i], _fresh_chain(x[i : i + 1], fs[i], 237.0, 0.03, 1.0)[0]
            )
    sos = SensorDynamics._design(2000.0, 237.0, 0.03, 1.0, 0.0, 2.0)
    assert not sos.flags.writeable  # shared between calls: nobody may change it
    assert SensorDynamics._design.cache_info().hits >= 1


def test_screen_settings_shorten_only_the_transient():
    s = screen_settings(FIT_SETTINGS_NUMERICAL)
    assert (
        s.settle_tolerance
        == fitting.SCREEN_SETTLE_TOLERANCE
        > FIT_SETTINGS_NUMERICAL.settle_tolerance
    )
    assert s.warm_start == fitting.SCREEN_WARM_START > FIT_SETTINGS_NUMERICAL.warm_start == 0
    assert s.model_dump() == {
        **FIT_SETTINGS_NUMERICAL.model_dump(),
        "settle_tolerance": s.settle_tolerance,
        "warm_start": s.warm_start,
    }
    loose = FIT_SETTINGS_NUMERICAL.model_copy(update={"settle_tolerance": 0.2, "warm_start": 1.0})
    assert screen_settings(loose) == loose  # never a longer transient than asked


def test_numerical_fit_with_the_short_screen_reports_what_the_full_screen_does(monkeypatch):
    """Hertz contact on two recordings with the inclinations on (so the best point is scored
    again in full): the shorter, warm-started screen keeps the same point, and the fit's
    numbers are bitwise those of a cold screen at the full transient."""
    rows = [ROW, ROW.model_copy(update={"recording": "b.csv", "beta": 60.0, "fs_hz": 1500})]
    n = [2500, 3000]
    sims = simulate_rows(rows, [], n, seed=3, settings=FIT_SETTINGS)
    measured = [
        signal_statistics(a, r.fs_hz, 9.48, 1.0, inclination=True)
        for a, r in zip(sims, rows, strict=True)
    ]

    def fit() -> dict:
        target = CampaignTarget(rows, measured, n, [], seed=11, inclination=True)
        return fit_effect(target, "hertz_contact", budget=3)

    short = fit()
    monkeypatch.setattr(fitting, "SCREEN_SETTLE_TOLERANCE", FIT_SETTINGS_NUMERICAL.settle_tolerance)
    monkeypatch.setattr(fitting, "SCREEN_WARM_START", 0.0)
    full = fit()
    assert short["params"] == full["params"]
    assert short["per_recording"] == full["per_recording"]
    assert short["off_per_recording"] == full["off_per_recording"]
    assert short["improves"] == full["improves"] and short["evaluations"] == full["evaluations"]
