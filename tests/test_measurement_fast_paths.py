"""The diagnosis' shortcuts give what the long way gives.

* The sensor chain's filter designs are kept per parameters: a filtered signal is bitwise
  the one a fresh design (scipy's ``butter``/``zpk2sos``/``sosfilt_zi``) gives.
* A numerical-engine effect's design, when its best point is scored again anyway, screens
  with a shorter transient (``fitting.SCREEN_SETTLE_TOLERANCE``) begun warm by the closed
  form (``fitting.SCREEN_WARM_START``): the point kept and every number reported are those
  of a cold screen at the fits' own transient.
* The screen's analog chain runs in for ``ln(1 / tol)`` of its slowest time constant, not
  the standard 1.5 s: its start-up transient is left at the screen's tolerance, and its white
  noise is the same whatever the lead-in's length.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as sps
from campaign_helpers import LAB_ROW

from stiffnet.campaign.simulate import (
    FIT_SETTINGS,
    FIT_SETTINGS_NUMERICAL,
    chain_time_constant,
    screen_lead_in_seconds,
    simulate_rows,
)
from stiffnet.effects.sensor_dynamics import SensorDynamics, resonance_sos
from stiffnet.measurement import fitting
from stiffnet.measurement.fitting import fit_effect, screen_settings
from stiffnet.measurement.statistics import signal_statistics
from stiffnet.measurement.target import CampaignTarget

SCREEN_TOLERANCE = fitting.SCREEN_SETTLE_TOLERANCE
ROW = LAB_ROW


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
    # an effect's design also runs the analog chain in to the screen's tolerance (the fits'
    # own settings: the standard lead-in), never to a tighter one than asked
    short = screen_settings(FIT_SETTINGS_NUMERICAL, short_lead_in=True)
    assert short == s.model_copy(update={"lead_in_tolerance": s.settle_tolerance})
    assert FIT_SETTINGS_NUMERICAL.lead_in_tolerance is None
    assert screen_settings(loose, short_lead_in=True).lead_in_tolerance == 0.2


def test_the_screen_lead_in_is_the_chains_slowest_time_constant():
    sensor = SensorDynamics(
        resonance_hz=237.0, resonance_damping=0.03, highpass_hz=1.0, lowpass_hz=0
    )
    # the high-pass is the slowest stage: 1 / (2 pi 1 Hz) = 0.159 s against the resonance's
    # 1 / (0.03 * 2 pi * 237 Hz) = 0.0224 s
    assert chain_time_constant(sensor) == pytest.approx(1 / (2 * np.pi))
    assert screen_lead_in_seconds([sensor], 0.05) == pytest.approx(np.log(20) / (2 * np.pi))
    # without the high-pass, a 2nd-order Butterworth at 5 Hz is slower than the resonance
    # (its poles decay at w_l sin(pi / 4))
    slow = SensorDynamics(resonance_hz=237.0, resonance_damping=0.03, highpass_hz=0, lowpass_hz=5)
    assert chain_time_constant(slow) == pytest.approx(1 / (2 * np.pi * 5 * np.sin(np.pi / 4)))
    assert screen_lead_in_seconds([], 0.05) == 0.0


def test_the_screen_lead_in_leaves_the_chains_start_up_at_its_tolerance():
    """The chain started ``m`` samples before a stretch of the same motion, against the chain
    started 1.5 s before it: what a start leaves on the stretch depends on the sample it
    starts at (a start on a spike rings the resonance hardest). After the screen's lead-in
    (ln 20 of the high-pass's time constant, 0.48 s) it is at most the screen's tolerance of
    the worst a start within 0.2 s of the stretch leaves, and under 1 % of the signal's swing
    (measured: 0.031 of 4.8 and 0.029 of 7.8; the worst starts 2.1 and 2.4). In a screen's
    simulation the white noise is the same whatever the lead-in."""
    rows = [ROW, ROW.model_copy(update={"recording": "b.csv", "beta": 60.0, "fs_hz": 2000})]
    sensor = SensorDynamics(
        resonance_hz=237.0, resonance_damping=0.03, highpass_hz=1.0, lowpass_hz=0
    )
    p = sensor.batch_params(1, np.random.default_rng(0))
    lead = screen_lead_in_seconds([sensor], 0.05)
    motion = simulate_rows(rows, [], [8000, 8000], seed=5, settings=FIT_SETTINGS)
    for r, x in zip(rows, motion, strict=True):
        fs, n = np.array([r.fs_hz]), int(r.fs_hz)  # compare one second from sample k
        k = int(np.ceil(1.5 * r.fs_hz))
        steady = sensor.apply(x[None, : k + n], fs, p, None)[0, k:]

        def left(seconds: float, x=x, fs=fs, n=n, k=k, steady=steady) -> float:
            m = int(np.ceil(seconds * fs[0]))
            return np.max(np.abs(sensor.apply(x[None, k - m : k + n], fs, p, None)[0, m:] - steady))

        start_up = max(left(t) for t in (0.0, 0.05, 0.1, 0.2))
        assert left(lead) <= SCREEN_TOLERANCE * start_up
        assert left(lead) < 0.01 * np.max(np.abs(steady))

    def run(tol, noise: bool) -> list[np.ndarray]:
        rs = rows if noise else [r.model_copy(update={"noise": 0.0}) for r in rows]
        settings = FIT_SETTINGS.model_copy(update={"lead_in_tolerance": tol})
        return simulate_rows(rs, [sensor], [3000, 4000], 5, settings, oversample=False)

    # the noise is added after the chain, drawn for the record's samples only
    for a, qa, b, qb in zip(run(None, True), run(None, False), run(0.05, True), run(0.05, False),
                            strict=True):  # fmt: skip
        np.testing.assert_allclose(b - qb, a - qa, rtol=1e-9, atol=1e-12)


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


def test_numerical_fit_on_a_sensor_reports_what_the_standard_lead_in_does(monkeypatch):
    """Hertz contact on top of a sensor chain (the model of a diagnosis's second step), two
    recordings: the screen with the chain's short lead-in keeps the point the standard 1.5-s
    lead-in keeps, and the fit's numbers (the kept point scored with the standard lead-in)
    are bitwise the same."""
    rows = [ROW, ROW.model_copy(update={"recording": "b.csv", "beta": 60.0, "fs_hz": 1500})]
    n = [2500, 3000]
    sensor = SensorDynamics(
        resonance_hz=237.0, resonance_damping=0.03, highpass_hz=1.0, lowpass_hz=0
    )
    sims = simulate_rows(rows, [sensor], n, seed=3, settings=FIT_SETTINGS)
    measured = [
        signal_statistics(a, r.fs_hz, 9.48, 1.0, inclination=False)
        for a, r in zip(sims, rows, strict=True)
    ]

    def fit() -> dict:
        target = CampaignTarget(rows, measured, n, [], seed=11, inclination=False)
        return fit_effect(target, "hertz_contact", fixed=[sensor], budget=3)

    short = fit()
    standard = fitting.screen_settings
    monkeypatch.setattr(fitting, "screen_settings", lambda s, short_lead_in=False: standard(s))
    full = fit()
    assert short["params"] == full["params"]
    assert short["per_recording"] == full["per_recording"]
    assert short["off_per_recording"] == full["off_per_recording"]
    assert short["improves"] == full["improves"] and short["evaluations"] == full["evaluations"]
