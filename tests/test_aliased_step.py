"""A damped contact's force step, sampled with no anti-alias filter: its aliases between the
forcing lines are left out of the state (stiffnet's engine samples the acceleration raw)."""

from __future__ import annotations

import numpy as np
import pytest

from serving.restoring_force_check import restoring_force_check
from stiffnet.restoring_force import restoring_force_estimate
from stiffnet.restoring_force.reconstruct import integrate_spectral
from stiffnet.uncertainty.unseen_law import unseen_law_reasons
from tests.test_restoring_force import FN, simulate


def test_the_forcing_lines_are_integrated_and_a_line_between_them_is_dropped():
    period = 250 / 3  # samples per forcing period, not a whole number
    n = int(round(21 * period))  # 21 periods: 1750 samples, whole
    dtau = 2 * np.pi / period
    tau = np.arange(n) * dtau
    lines = np.cos(tau) + 0.3 * np.sin(5 * tau)
    vel, disp = integrate_spectral(lines + 0.1 * np.cos(tau / 3), dtau, forcing_lines_only=True)
    np.testing.assert_allclose(vel, np.sin(tau) - 0.06 * np.cos(5 * tau), atol=1e-9)
    np.testing.assert_allclose(disp, -np.cos(tau) - 0.012 * np.sin(5 * tau), atol=1e-9)
    plain = integrate_spectral(lines + 0.1 * np.cos(tau / 3), dtau)[1]
    assert np.max(np.abs(plain - disp)) == pytest.approx(0.9, rel=1e-6)  # 0.1 / (1/3)**2


@pytest.mark.parametrize(
    ("beta", "zeta_c", "omega", "gap"),
    [
        # the joint fit read 3.61 [2.60, 5.02] from the state its aliased onset steps bent;
        # 5.53 from the forcing lines, its interval [3.59, 5.96] reaching the record's own
        (5.5, 0.2, 1.2, 0.8),
        # the map read 17.6 [14.8, 21.1]; 20.2 [14.8, 23.4] with beta's scale from the forcing
        # lines (the interval spans the record's own integration's)
        (20.0, 0.3, 1.1, 1.0),
    ],
)
def test_a_damped_contact_sampled_raw_is_read_within_five_percent(beta, zeta_c, omega, gap):
    """A damped contact, 100 samples per natural period (83.3 and 90.9 per forcing period),
    2 % noise, no chain: beta within 5 %, its interval covering."""
    accel, fs = simulate(beta, [("contact_damping", {"damping_ratio": zeta_c})], fs_ratio=100,
                         periods=40, noise=0.02, omega=omega, gap=gap)  # fmt: skip
    got = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, max_periods=24, sensor={})
    assert got.ok, got.reason
    assert got.beta == pytest.approx(beta, rel=0.05)
    assert got.beta_interval[0] <= beta <= got.beta_interval[1]


def test_only_betas_scale_is_read_from_the_forcing_lines():
    """Beta 20, zeta_c 0.3 raw: beta is the lines' map's, its interval reaching the record's
    own reading (17.6); the law's shape is the record's map's: its damping ratio, and a linear
    exponent with an onset per impact that fires no unseen-law reason. An elastic contact
    (no onset step to alias) is read from the record alone."""
    accel, fs = simulate(20.0, [("contact_damping", {"damping_ratio": 0.3})], fs_ratio=100,
                         periods=40, noise=0.02, omega=1.1, gap=1.0)  # fmt: skip
    check = restoring_force_check(accel, fs, FN)
    assert "forcing lines alone" in check["reason"], check["reason"]
    record_beta = float(check["reason"].rsplit("reads ", 1)[1].rstrip(")"))
    lo, hi = check["beta_interval"]
    assert record_beta < 0.95 * 20.0 and lo <= record_beta <= hi
    assert check["beta"] == pytest.approx(20.0, rel=0.05)
    assert check["contact_damping_ratio"] == pytest.approx(0.3, abs=0.05)
    assert check["impact_onsets"]["exponent"] <= 1.2, check["impact_onsets"]
    assert unseen_law_reasons(check) == []
    elastic, fs = simulate(20.0, fs_ratio=100, periods=40, noise=0.02, omega=1.1, gap=1.0)
    got = restoring_force_estimate(elastic, fs, natural_frequency_hz=FN, max_periods=24, sensor={})
    assert got.ok and "forcing lines" not in got.reason, got.reason
    assert got.beta == pytest.approx(20.0, rel=0.05)
