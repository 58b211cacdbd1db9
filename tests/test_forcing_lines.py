"""The shaker's harmonics read off the free flights (the closed-form global stage of their
fit): analytic linear records, the simulator's impacting ones, and the fit space built
around the reading."""

from __future__ import annotations

import math

import numpy as np
import pytest
from campaign_helpers import LAB_ROW

from stiffnet.campaign.simulate import FIT_SETTINGS, simulate_rows
from stiffnet.effects.fit_space import global_blocks
from stiffnet.effects.forcing_harmonics import READ_RADIUS_MIN, READ_RADIUS_SE, ForcingHarmonics
from stiffnet.effects.registry import effect_class
from stiffnet.measurement.forcing_lines import (
    campaign_forcing_lines,
    recording_forcing_lines,
    spikes_polarity,
)

ROW = LAB_ROW.model_copy(update={"noise": None})


def _linear_record(ratio, zeta, h, theta, fs_per_period=120, periods=12):
    """Steady state of ``x'' + c x' + k x = F(tau)`` (no contact) and ``y = x'' - F``,
    ``F = sin(tau + theta) + sum h_m sin(m tau + m theta + phi_m)``: the forcing's lines
    pass through the oscillator's transfer ``1 / (k - m**2 + i c m)``."""
    k = 1 / ratio**2
    c = 2 * zeta * math.sqrt(k)
    tau = np.arange(fs_per_period * periods) * 2 * math.pi / fs_per_period
    y = np.zeros_like(tau)
    for m, (a, phi) in {1: (1.0, 0.0), **h}.items():
        z = a * np.exp(1j * (m * theta + phi)) / (k - m**2 + 1j * c * m)
        x = (z * np.exp(1j * m * tau)).imag
        v = (1j * m * z * np.exp(1j * m * tau)).imag
        y += -c * v - k * x
    return y, k, c


@pytest.mark.parametrize("theta", [0.0, 1.3, -2.7])
def test_a_linear_record_gives_its_harmonics_whatever_its_start_time(theta):
    h = {2: (0.25, 1.1), 3: (0.12, -2.0)}
    y, k, c = _linear_record(1.1, 0.03, h, theta)
    z = recording_forcing_lines(y, 120.0, 1.0, k, c)
    # no spikes: the record is read at the polarity its excursions say, and a record read
    # upside down has its second harmonic turned by pi (the third stays)
    turn = 0.0 if spikes_polarity(y) == -1 else math.pi
    assert abs(z[0]) == pytest.approx(0.25, rel=1e-3)
    assert abs(z[1]) == pytest.approx(0.12, rel=1e-3)
    assert math.remainder(np.angle(z[0]) - 1.1 - turn, 2 * math.pi) == pytest.approx(0, abs=1e-3)
    assert math.remainder(np.angle(z[1]) + 2.0, 2 * math.pi) == pytest.approx(0, abs=1e-3)
    # a sensor mounted the other way reads the same
    np.testing.assert_allclose(recording_forcing_lines(-y, 120.0, 1.0, k, c), z, atol=1e-9)


def test_no_harmonics_read_as_none_and_a_short_record_is_not_read():
    y, k, c = _linear_record(0.9, 0.02, {}, 0.4)
    assert np.all(np.abs(recording_forcing_lines(y, 120.0, 1.0, k, c)) < 1e-6)
    assert recording_forcing_lines(y[:300], 120.0, 1.0, k, c) is None  # 2.5 periods


def test_an_impacting_campaign_from_the_simulator_is_read_within_a_few_percent():
    """Impacts every period (beta 30, gap 1.2, amplitude 1.2), 2 % noise: the impacts are
    split off as outliers of the free-flight law, the lines read on the flights."""
    truth = {"second": 0.2, "phase_second": -2.4, "third": 0.08, "phase_third": 2.2}
    rows = [
        ROW.model_copy(update={"recording": f"r{i}.csv", "frequency_ratio": r, "beta": b})
        for i, (r, b) in enumerate([(0.95, 20), (1.0, 30), (1.05, 60), (1.1, 90)])
    ]
    sims = simulate_rows(rows, [effect_class("forcing_harmonics")(**truth)], [5000] * 4, 3,
                         FIT_SETTINGS)  # fmt: skip
    read = campaign_forcing_lines(sims, rows)
    assert read["read"] == 4
    assert read["second"] == pytest.approx(0.2, rel=0.05)
    assert read["third"] == pytest.approx(0.08, rel=0.05)
    for k in ("phase_second", "phase_third"):
        assert abs(math.remainder(read[k] - truth[k], 2 * math.pi)) < 0.05, read
    assert 0 < read["second_se"] < 0.01 and 0 < read["third_se"] < 0.01
    # the simulator without harmonics reads next to none
    plain = campaign_forcing_lines(simulate_rows(rows, [], [5000] * 4, 3, FIT_SETTINGS), rows)
    assert plain["second"] < 0.01 and plain["third"] < 0.01


def test_the_fit_starts_at_the_reading_and_searches_its_confidence_region():
    space = ForcingHarmonics.campaign_fit_space(1000.0)
    assert global_blocks(space) == []  # the reading stands for the grid over the phases
    assert set(space.multimodal) == {"phase_second", "phase_third"}
    assert ForcingHarmonics.fit_seeds({}, space) == []
    assert ForcingHarmonics.observed_fit_space(space, {}) is space
    read = {"second": 0.25, "phase_second": 1.0, "third": 0.6, "phase_third": -2.0}
    observed = {f"forcing_{k}": v for k, v in read.items()}
    observed.update(forcing_second_se=0.01, forcing_third_se=0.0)
    (seed,) = ForcingHarmonics.fit_seeds(observed, space)
    assert seed["third"] == 0.5  # clipped to the declared range
    box = ForcingHarmonics.observed_fit_space(space, observed)
    bounds = {fp.name: (fp.low, fp.high) for fp in box.free}
    r2, r3 = READ_RADIUS_SE * 0.01, READ_RADIUS_MIN
    assert bounds["second_cos"] == pytest.approx((0.25 * math.cos(1) - r2, 0.25 * math.cos(1) + r2))
    assert bounds["third_sin"] == pytest.approx((0.5 * math.sin(-2) - r3, 0.5 * math.sin(-2) + r3))
    # the reading is the centre of the box
    centre = box.params(np.full(4, 0.5))
    assert centre["second"] == pytest.approx(0.25) and centre["phase_second"] == pytest.approx(1)
    assert centre["third"] == pytest.approx(0.5) and centre["phase_third"] == pytest.approx(-2)
