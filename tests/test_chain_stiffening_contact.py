"""The chain fit against a restraint that stiffens with penetration.

A two-stage, power-law or Hunt-Crossley restraint starts its pulse slowly, as a low-pass
does. Recordings from the independent solve_ivp rig (tests/independent_rig.py), whose
chain is scipy.signal's on an oversampled motion.
"""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.restoring_force import identify_sensor_chain
from stiffnet.restoring_force.chain import contact_pulse
from tests.independent_rig import RigRun, record

FN = 9.48


def test_a_stiffening_pulse_rises_slower_than_the_linear_one_over_the_same_half_period():
    """The contact shape's exponent: 1 is the linear pulse bit for bit; 1.5 is the classical
    ``sin^(3/2)`` shape of a Hertz contact's pulse, as wide at half its peak as the linear
    pulse of the same contact frequency (so it lasts longer and starts slower)."""
    t = np.linspace(-0.002, 0.03, 32001)
    linear = contact_pulse(t, 50.0, 0.0, 0.0, 0.0)
    assert np.array_equal(contact_pulse(t, 50.0, 0.0, 0.0, 0.0, exponent=1.0), linear)
    hertz = contact_pulse(t, 50.0, 0.0, 0.0, 0.0, exponent=1.5)
    # sin^1.5 is half its peak at arcsin(2^(-2/3)): the frequency that keeps the width
    w = 2 * np.pi * 50.0 * (np.pi - 2 * np.arcsin(2 ** (-2 / 3))) / (2 * np.pi / 3)
    half_period = np.pi / w
    inside = (t > 0) & (t < half_period - 1e-5)
    expected = w * np.sin(w * t[inside]) ** 1.5
    assert hertz[inside] == pytest.approx(expected, rel=1e-9, abs=1e-9 * w)
    assert np.all(hertz[t > half_period + 1e-5] == 0.0) and np.all(hertz[t < 0] == 0.0)

    def width(f):
        above = t[f >= 0.5 * f.max()]
        return above[-1] - above[0]

    assert width(hertz) == pytest.approx(width(linear), abs=2e-6)
    early = inside & (t < 0.002)
    assert np.all(hertz[early] / hertz.max() < linear[early] / linear.max())


@pytest.mark.parametrize(
    ("beta", "forcing_hz", "base_g", "gap_mm", "fs_hz"),
    [(13.0, 9.29, 0.521, 1.6, 1500.0), (15.0, 9.48, 0.434, 1.2, 1250.0)],
)
def test_a_two_stage_restraint_with_no_chain_is_given_no_lowpass(
    beta, forcing_hz, base_g, gap_mm, fs_hz
):
    """Independent rig, a two-stage restraint (x2.5 beyond a 0.25 mm knee) and no sensor
    chain at all, 2 % noise: with a linear contact alone the chain fit read the soft toe as
    a 2nd-order low-pass of 112-138 Hz (its campaign: a low-pass on 5 of 6 records)."""
    run = RigRun(recording="r.csv", beta=beta, forcing_frequency_hz=forcing_hz,
                 base_acceleration_g=base_g, gap_mm=gap_mm, fs_hz=fs_hz, duration_s=3.0,
                 contact="two_stage", knee_mm=0.25, stage_ratio=2.5)  # fmt: skip
    got = identify_sensor_chain(record(run, seed=11)[1], fs_hz, FN, forcing_hz)
    assert got is not None
    assert got.lowpass_hz is None and got.resonance_hz is None


@pytest.mark.parametrize(
    ("beta", "forcing_hz", "base_g", "gap_mm", "fs_hz"),
    [(83.0, 9.01, 0.327, 0.5, 1000.0), (89.0, 9.95, 0.757, 2.8, 1500.0)],
)
def test_a_lowpass_behind_a_power_law_contact_is_found_at_its_corner(
    beta, forcing_hz, base_g, gap_mm, fs_hz
):
    """Independent rig, a power-law restraint (n 1.6) behind a true 2nd-order 250 Hz
    low-pass: with a linear contact alone the fit made the low-pass take the contact's soft
    start too, and its corner tracked beta (197-222 Hz at beta 83-89, 131 Hz at 12)."""
    run = RigRun(recording="r.csv", beta=beta, forcing_frequency_hz=forcing_hz,
                 base_acceleration_g=base_g, gap_mm=gap_mm, fs_hz=fs_hz, duration_s=3.0,
                 contact="power_law", power_exponent=1.6, power_d0_mm=0.4,
                 sensor={"lowpass_hz": 250.0, "lowpass_order": 2})  # fmt: skip
    got = identify_sensor_chain(record(run, seed=11)[1], fs_hz, FN, forcing_hz)
    assert got is not None and got.resonance_hz is None
    assert got.lowpass_order == 2
    assert got.lowpass_hz == pytest.approx(250.0, rel=0.1)
