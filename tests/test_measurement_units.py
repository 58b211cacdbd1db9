"""Unit tests of the measurement package: statistics, discrepancy, significance, fit spaces."""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.campaign import ManifestRow
from stiffnet.effects.registry import CANONICAL, effect_class
from stiffnet.errors import SignalError
from stiffnet.measurement.diagnose import (
    FIT_SPACES,
    CampaignTarget,
    coarse_grid,
    fit_effect,
    fit_space,
    objective_value,
    significance,
)
from stiffnet.measurement.discrepancy import (
    COMPONENTS,
    TOLERANCES,
    normalised_differences,
    recording_discrepancy,
)
from stiffnet.measurement.simulate import FIT_SETTINGS, SolverSettings, simulate_rows
from stiffnet.measurement.statistics import signal_statistics

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
FAR = ROW.model_copy(update={"recording": "far.csv", "gap": 50.0})


@pytest.fixture(scope="module")
def signal():
    return simulate_rows([ROW], [], [5000], settings=SolverSettings(periods=40))[0]


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
    free = simulate_rows([FAR], [], [4000], settings=SolverSettings(periods=40))[0]
    s = signal_statistics(free, 1250, 9.48, 1.0)
    assert not s.has_impacts and s.waveform.size == 0 and np.isnan(s.spike_height)
    assert s.harmonics[1] < 0.05  # a linear oscillator: almost no harmonics
    with pytest.raises(SignalError):
        signal_statistics(np.ones(1000), 1250, 9.48, 1.0)
    with pytest.raises(SignalError):
        signal_statistics(free[:50], 1250, 9.48, 1.0)


def test_discrepancy_of_contact_mismatch_is_large(signal):
    free = simulate_rows([FAR], [], [4000], settings=SolverSettings(periods=40))[0]
    a, b = signal_statistics(signal, 1250, 9.48, 1.0), signal_statistics(free, 1250, 9.48, 1.0)
    d = normalised_differences(a, b)
    assert set(d) == set(COMPONENTS) == set(TOLERANCES)
    assert np.isnan(d["waveform"])  # needs impacts on both sides
    assert abs(d["impact_rate"]) > 5 and recording_discrepancy(d) > 10


def test_simulation_is_deterministic_and_seeded(signal):
    again = simulate_rows([ROW], [], [5000], settings=SolverSettings(periods=40))[0]
    np.testing.assert_array_equal(signal, again)
    other = simulate_rows([ROW], [], [5000], seed=1, settings=SolverSettings(periods=40))[0]
    assert not np.array_equal(signal, other)
    assert signal.size == 5000  # the wanted length, under 40 natural periods
    short = simulate_rows([ROW], [], [9000], settings=SolverSettings(periods=20))[0]
    assert short.size == int(np.ceil(20 * 1250 / 9.48))


def test_objective_trims_the_worst_recordings():
    assert objective_value(np.zeros(8)) == 0.0
    assert objective_value(np.r_[np.zeros(6), 1e6, 1e6]) == 0.0  # two outliers of eight dropped
    assert objective_value(np.r_[np.zeros(5), 1e6, 1e6, 1e6]) > 1.0


def test_significance_rule():
    base = np.full(8, 4.0)
    sig = significance(base, np.full(8, 0.1), k=1)
    assert sig["significant"] and sig["sign_test_p"] < 0.01
    # one outlier carrying the whole reduction is not significant
    fitted = base.copy()
    fitted[3] = 0.0
    base_out = base.copy()
    base_out[3] = 400.0
    sig = significance(base_out, fitted + 0.001, k=1)
    assert sig["relative_reduction"] > 0.5 and not sig["significant"]
    # a small consistent improvement does not pay for its parameters
    assert not significance(base, base - 0.05, k=2)["significant"]


def test_fit_spaces_are_inside_declared_ranges():
    rows = [ROW]
    for name in CANONICAL:
        table = {r["name"]: r["range"] for r in effect_class(name).parameter_table()}
        space = fit_space(name, rows)
        assert name in FIT_SPACES
        for fp in space.free:
            lo, hi = table[fp.name]
            assert lo <= fp.low < fp.high <= hi
            assert fp.unit(fp.value(0.3)) == pytest.approx(0.3)
        for k, v in space.fixed.items():
            assert table[k][0] <= v <= table[k][1]
        effect_class(name)(**space.fixed, **{fp.name: fp.value(0.5) for fp in space.free})
    user = fit_space("user_effects:Gain", rows)
    assert [fp.name for fp in user.free] == ["gain"]
    assert coarse_grid(user.free).shape == (9, 1)


def test_numerical_effect_fit_runs_within_budget():
    """A Hertz-contact fit: the numerical engine, one batch per evaluation, tiny budget."""
    rows = [ROW, ROW.model_copy(update={"recording": "b.csv", "beta": 60.0, "fs_hz": 1500})]
    sims = simulate_rows(rows, [], [3000, 3000], seed=3, settings=FIT_SETTINGS)
    measured = [signal_statistics(a, r.fs_hz, 9.48, 1.0) for a, r in zip(sims, rows, strict=True)]
    target = CampaignTarget(rows, measured, [3000, 3000], [], seed=11, inclination=False)
    fit = fit_effect(target, "hertz_contact", budget=2)
    assert fit["engine"] == "numerical" and fit["evaluations"] == 2
    assert set(fit["params"]) == {"reference_penetration"}
    assert len(fit["per_recording"]) == 2
