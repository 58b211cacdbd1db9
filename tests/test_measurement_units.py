"""Unit tests of the measurement package: statistics, discrepancy, significance, fit spaces."""

from __future__ import annotations

import math

import numpy as np
import pytest
from campaign_helpers import LAB_ROW

from stiffnet.campaign.simulate import FIT_SETTINGS, CampaignSolverSettings, simulate_rows
from stiffnet.effects.registry import CANONICAL, effect_class
from stiffnet.errors import SignalError
from stiffnet.measurement import fitting
from stiffnet.measurement.discrepancy import (
    COMPONENTS,
    TOLERANCES,
    normalised_differences,
    recording_discrepancy,
)
from stiffnet.measurement.fitting import effect_space, fit_effect, initial_design, objective_value
from stiffnet.measurement.significance import significance
from stiffnet.measurement.statistics import signal_statistics
from stiffnet.measurement.target import CampaignTarget

ROW = LAB_ROW
FAR = ROW.model_copy(update={"recording": "far.csv", "gap": 50.0})


@pytest.fixture(scope="module")
def signal():
    return simulate_rows([ROW], [], [5000], settings=CampaignSolverSettings(periods=40))[0]


def test_statistics_are_gain_and_polarity_free(signal):
    a = signal_statistics(signal, 1250, 9.48, 1.0)
    for other in (1000.0 * signal, -signal):
        b = signal_statistics(other, 1250, 9.48, 1.0)
        d = normalised_differences(a, b)
        assert recording_discrepancy(d) < 1e-12
    assert a.has_impacts
    assert a.impacts_per_period == pytest.approx(1.0, abs=0.05)  # period-1 impacting orbit
    assert 0 < a.spike_width < 0.2 and a.spike_height > 3
    assert np.isfinite(a.inclination_before_deg)


def test_statistics_without_contact_and_bad_input():
    free = simulate_rows([FAR], [], [4000], settings=CampaignSolverSettings(periods=40))[0]
    s = signal_statistics(free, 1250, 9.48, 1.0)
    assert not s.has_impacts and s.waveform.size == 0 and np.isnan(s.spike_height)
    assert s.harmonics[1] < 0.05  # a linear oscillator: almost no harmonics
    with pytest.raises(SignalError):
        signal_statistics(np.ones(1000), 1250, 9.48, 1.0)
    with pytest.raises(SignalError):
        signal_statistics(free[:50], 1250, 9.48, 1.0)


def test_discrepancy_of_contact_mismatch_is_large(signal):
    free = simulate_rows([FAR], [], [4000], settings=CampaignSolverSettings(periods=40))[0]
    a, b = signal_statistics(signal, 1250, 9.48, 1.0), signal_statistics(free, 1250, 9.48, 1.0)
    d = normalised_differences(a, b)
    assert set(d) == set(COMPONENTS) == set(TOLERANCES)
    assert np.isnan(d["waveform"])  # needs impacts on both sides
    assert abs(d["impact_rate"]) > 5 and recording_discrepancy(d) > 10


def test_simulation_is_deterministic_and_seeded(signal):
    again = simulate_rows([ROW], [], [5000], settings=CampaignSolverSettings(periods=40))[0]
    np.testing.assert_array_equal(signal, again)
    other = simulate_rows([ROW], [], [5000], seed=1, settings=CampaignSolverSettings(periods=40))[0]
    assert not np.array_equal(signal, other)
    assert signal.size == 5000  # the wanted length, under 40 natural periods
    short = simulate_rows([ROW], [], [9000], settings=CampaignSolverSettings(periods=20))[0]
    assert short.size == int(np.ceil(20 * 1250 / 9.48))


def test_objective_is_the_campaign_discrepancy():
    per = np.array([0.0, 1.0, 2.0, 5.0])
    assert objective_value(per) == pytest.approx(2.0)  # the number reported, not a proxy


def test_significance_rule_and_reasons():
    base = np.full(8, 4.0)
    sig = significance(base, np.full(8, 0.1), k=1, floor=0.05)
    assert sig["significant"] and sig["reasons"] == []
    assert sig["excess_reduction"] == pytest.approx((4.0 - 0.1) / (4.0 - 0.05))
    # one outlier carrying the whole reduction is not significant, and says so
    fitted, base_out = base.copy(), base.copy()
    fitted[3], base_out[3] = 0.0, 400.0
    sig = significance(base_out, fitted + 0.001, k=1, floor=0.05, recordings=list("abcdefgh"))
    assert sig["relative_reduction"] > 0.5 and not sig["significant"]
    assert not sig["tests"]["not_one_recording"]
    assert any("without d" in r for r in sig["reasons"])
    # a model already at the noise floor has nothing to explain
    sig = significance(np.full(8, 0.05), np.full(8, 0.01), k=1, floor=0.05)
    assert not sig["significant"] and "noise floor" in sig["reasons"][0]
    # five recordings, four improved: a paired bootstrap still sees it (a sign test cannot)
    sig = significance(np.array([3.0, 2.5, 4.0, 2.0, 1.0]), np.array([0.2, 0.3, 0.5, 0.1, 1.2]),
                       k=1, floor=0.05)  # fmt: skip
    assert sig["significant"], sig["reasons"]


def test_fit_spaces_are_declared_by_the_effects_inside_their_ranges():
    rows = [ROW]
    for name in CANONICAL:
        cls = effect_class(name)
        assert cls.fit_space is not None  # each shipped effect declares its own
        table = {r["name"]: r["range"] for r in cls.parameter_table()}
        space = effect_space(name, rows)
        for k in space.fitted:
            assert k in table
        for k, v in space.fixed.items():
            assert table[k][0] <= v <= table[k][1]
        for u in (
            np.zeros(len(space.free)),
            np.full(len(space.free), 0.3),
            np.ones(len(space.free)),
        ):
            p = space.params(u)
            for k in space.fitted:
                assert table[k][0] <= p[k] <= table[k][1], (name, k, p[k])
            cls(**p)
            back = space.params(space.unit(p))
            np.testing.assert_allclose([back[k] for k in p], [p[k] for k in p], atol=1e-9)
    # harmonics: phases are fitted (in Cartesian coordinates), not pinned at zero
    h = effect_space("forcing_harmonics", rows)
    assert {"phase_second", "phase_third"} <= set(h.fitted)
    p = h.params(np.array([0.5, 0.9, 0.2, 0.5]))
    assert p["phase_second"] == pytest.approx(math.pi / 2) and p["second"] == pytest.approx(0.4)
    # the sensor's resonance stays below 0.45 fs of the slowest recording
    assert effect_space("sensor_dynamics", rows).free[0].high == pytest.approx(0.45 * 1250)
    user = effect_space("user_effects:Gain", rows)
    assert [fp.name for fp in user.free] == ["gain"]
    assert initial_design(user).shape == (9, 1)


def test_numerical_effect_fit_runs_within_budget(monkeypatch):
    """A Hertz-contact fit: the numerical engine, its design as one batch, tiny budget."""
    rows = [ROW, ROW.model_copy(update={"recording": "b.csv", "beta": 60.0, "fs_hz": 1500})]
    sims = simulate_rows(rows, [], [3000, 3000], seed=3, settings=FIT_SETTINGS)
    measured = [signal_statistics(a, r.fs_hz, 9.48, 1.0) for a, r in zip(sims, rows, strict=True)]
    target = CampaignTarget(rows, measured, [3000, 3000], [], seed=11, inclination=False)
    fit = fit_effect(target, "hertz_contact", budget=2)
    assert fit["engine"] == "numerical" and fit["evaluations"] in (2, 3)
    assert set(fit["params"]) == {"reference_penetration"}
    assert len(fit["per_recording"]) == 2 and min(fit["per_recording"]) >= 0
    off = np.asarray(fit["off_per_recording"])
    assert objective_value(np.asarray(fit["per_recording"])) <= objective_value(off)
    # on a larger campaign the design runs on a subset, the best point is scored on all
    monkeypatch.setattr(fitting, "SUBSET_NUMERICAL", 1)
    sub = fit_effect(target, "hertz_contact", budget=2)
    assert len(sub["searched_on"]) == 1 and len(sub["per_recording"]) == 2
    assert sub["evaluations"] in (3, 4)  # design, off on the subset, the best on all if it helps
    off = np.asarray(sub["off_per_recording"])
    assert objective_value(np.asarray(sub["per_recording"])) <= objective_value(off)


def test_design_points_as_one_batch_match_single_evaluations():
    """per_recording_points: the campaign's rows once per point in one batch; each point
    scores what it scores alone (exactly without noise; the first point also with noise)."""
    from stiffnet.campaign.simulate import FIT_SETTINGS_NUMERICAL

    quiet = ROW.model_copy(update={"noise": 0.0})
    rows = [quiet, quiet.model_copy(update={"recording": "b.csv", "beta": 60.0})]
    for rows_, exact_all in ((rows, True), ([ROW, rows[1]], False)):
        sims = simulate_rows(rows_, [], [3000, 3000], seed=3, settings=FIT_SETTINGS)
        measured = [signal_statistics(a, 1250, 9.48, 1.0) for a in sims]
        target = CampaignTarget(rows_, measured, [3000, 3000], [], seed=11, inclination=False)
        points = [{"reference_penetration": v} for v in (0.02, 0.2)]
        cls = effect_class("hertz_contact")
        batch = target.per_recording_points([], "hertz_contact", points, FIT_SETTINGS_NUMERICAL)
        alone = [target.per_recording([cls(**p)], FIT_SETTINGS_NUMERICAL) for p in points]
        np.testing.assert_array_equal(batch[0], alone[0])
        if exact_all:
            np.testing.assert_array_equal(batch[1], alone[1])
        assert not np.array_equal(batch[0], batch[1])  # the points differ


def test_search_leaves_the_inclinations_out_and_scores_the_best_with_them(signal):
    """With inclination statistics on, the search runs without them, and the reported
    discrepancies (best point and effect off) are scored with every statistic."""
    rows = [ROW]
    measured = [signal_statistics(signal, 1250, 9.48, 1.0, inclination=True)]
    target = CampaignTarget(rows, measured, [signal.size], [], seed=11, inclination=True)
    cheap = target.per_recording([], FIT_SETTINGS, inclination=False)
    full = target.per_recording([], FIT_SETTINGS)
    assert cheap[0] != full[0]  # the inclination components count in the full one
    fit = fit_effect(target, "contact_damping", budget=4)
    assert fit["off_per_recording"] == pytest.approx(full.tolist())
    p = effect_class("contact_damping")(**fit["params"])
    scored = target.per_recording([p], FIT_SETTINGS)
    assert fit["per_recording"] == pytest.approx(scored.tolist())
    assert fit["evaluations"] == 5  # 4 searched, the best scored with every statistic


def test_forcing_frequency_from_the_spectrum(signal):
    from stiffnet.measurement.nuisance import forcing_frequency_ratio

    t = np.arange(4000) / 1250.0
    tone = np.sin(2 * np.pi * 1.037 * 9.48 * t) + 0.1 * np.random.default_rng(0).normal(size=t.size)
    assert forcing_frequency_ratio(tone, 1250.0, 9.48) == pytest.approx(1.037, rel=2e-3)
    # an impacting record: the forcing line, not an impact harmonic (ROW's ratio is 1.0)
    assert forcing_frequency_ratio(signal, 1250.0, 9.48) == pytest.approx(1.0, rel=5e-3)


def test_physical_units_become_model_units_and_bad_ones_are_refused():
    from stiffnet.campaign import ManifestRow

    f_f = 1.05 * 9.48
    acc_g = 1.9e-3 * (2 * np.pi * f_f) ** 2 / 9.80665  # 1.9 mm of table motion
    r = ManifestRow(recording="a.csv", fs_hz=1000, forcing_frequency_hz=f_f,
                    base_acceleration_g=acc_g, base_acceleration_g_tol=0.1 * acc_g,
                    gap_mm=2.8, gap_mm_tol=0.2)  # fmt: skip
    assert r.frequency_ratio == pytest.approx(1.05)
    assert r.amplitude == pytest.approx(1.9) and r.amplitude_tol == pytest.approx(0.19)
    assert r.gap == pytest.approx(2.8) and r.gap_tol == pytest.approx(0.2)
    assert ManifestRow(recording="a.csv", fs_hz=1000, base_displacement_mm=1.2).amplitude == 1.2
    with pytest.raises(ValueError, match="forcing_frequency_hz"):
        ManifestRow(recording="a.csv", fs_hz=1000, base_acceleration_ms2=3.0)
    with pytest.raises(ValueError, match="disagrees"):
        ManifestRow(recording="a.csv", fs_hz=1000, gap=1.0, gap_mm=2.0)
