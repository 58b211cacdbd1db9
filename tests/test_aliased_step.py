"""A damped contact's force step, sampled with no anti-alias filter: its aliases between the
forcing lines are left out of the state (stiffnet's engine samples the acceleration raw)."""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.restoring_force import restoring_force_estimate
from stiffnet.restoring_force.reconstruct import integrate_spectral
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


def test_a_soft_damped_contact_sampled_raw_is_read_within_five_percent():
    """Beta 5.5, zeta_c 0.2, 83.3 samples per forcing period, 2 % noise, no chain: the joint
    fit read 3.61 [2.60, 5.02] from the state its aliased onset steps bent; 5.53 from the
    forcing lines, its interval [3.59, 5.96] reaching the record's own reading."""
    accel, fs = simulate(5.5, [("contact_damping", {"damping_ratio": 0.2})], fs_ratio=100,
                         periods=40, noise=0.02, omega=1.2, gap=0.8)  # fmt: skip
    got = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, max_periods=24, sensor={})
    assert got.ok, got.reason
    assert got.beta == pytest.approx(5.5, rel=0.05)
    assert got.beta_interval[0] <= 5.5 <= got.beta_interval[1]
