"""geometric_estimate end to end: invariances, no-contact windows, bad input, speed."""

import json
import time

import numpy as np
import pytest

from stiffnet.errors import ConfigError, SignalError
from stiffnet.geometry import NO_CONTACT, dominant_period, geometric_estimate, load_calibration
from stiffnet.geometry.paper import simulate_paper
from stiffnet.simulator.batch import PAPER_NATURAL_FREQUENCY_HZ, OscillatorBatch
from stiffnet.simulator.simulator import Simulator

FS_RATIO = 100.0
FS_HZ = FS_RATIO * PAPER_NATURAL_FREQUENCY_HZ


@pytest.fixture(scope="module")
def windows():
    """16-natural-period windows (the dataset's): paper system at beta 12 and 47, 2 % noise."""
    res = simulate_paper([12.0, 47.0], n_samples=1600, noise=0.02)
    return res.accel


@pytest.fixture(scope="module")
def no_impact():
    """The same system with a gap the mass never reaches."""
    batch = OscillatorBatch.single(26.0, 30.0, 1.9, 1.05, 0.02)
    return Simulator().simulate(batch, FS_RATIO, 1600, noise=0.02, rng=1).accel[0]


def test_impacting_window_gets_a_class_and_beta(windows):
    soft, hard = (geometric_estimate(w, FS_HZ) for w in windows)
    for r in (soft, hard):
        assert r.contact_detected and r.n_orbits >= 14
        assert r.delay == 17 and r.tangent_lag == 1 and r.dimension >= 3
        assert r.period_samples == pytest.approx(FS_RATIO / 1.05, rel=0.01)
        assert r.polarity == -1  # our simulator's spikes point down
        assert 0 < r.contact_fraction < 0.6 and np.isfinite(r.threshold)
        assert r.impacts.size == pytest.approx(r.n_orbits, abs=2)
        assert r.orbit_before_deg.size == r.orbit_after_deg.size == r.n_orbits
        assert r.inclination_after_deg > r.inclination_before_deg
    assert soft.geometric_class == "soft" and hard.geometric_class == "hard"
    assert soft.geometric_beta < hard.geometric_beta
    json.dumps(soft.to_dict())  # JSON-ready


def test_gain_and_polarity_do_not_change_the_estimate(windows):
    ref = geometric_estimate(windows[0], FS_HZ)
    for variant in (1000.0 * windows[0], -windows[0], -1e-3 * windows[0] + 5.0):
        r = geometric_estimate(variant, FS_HZ)
        assert r.geometric_class == ref.geometric_class
        assert r.geometric_beta == pytest.approx(ref.geometric_beta, rel=1e-6)
        assert r.inclination_before_deg == pytest.approx(ref.inclination_before_deg, abs=1e-6)
        assert r.inclination_after_deg == pytest.approx(ref.inclination_after_deg, abs=1e-6)
        assert r.n_orbits == ref.n_orbits
    # the polarity is detected and reported, nothing else depends on it
    assert geometric_estimate(-windows[0], FS_HZ).polarity == 1


def test_window_without_impacts_is_no_contact(no_impact):
    r = geometric_estimate(no_impact, FS_HZ)
    assert not r.contact_detected
    assert r.geometric_class == NO_CONTACT and r.geometric_beta is None
    assert np.isnan(r.inclination_before_deg) and r.n_orbits == 0
    assert r.threshold == np.inf and r.contact_fraction == 0.0
    assert "one mode" in r.reason
    assert r.to_dict()["inclination_after_deg"] is None


def test_without_calibration_angles_only(windows):
    r = geometric_estimate(windows[1], FS_HZ, calibration=None)
    assert r.geometric_beta is None and r.geometric_class is None
    assert np.isfinite(r.inclination_after_deg)


def test_options(windows):
    g = geometric_estimate(windows[0], FS_HZ, method="gradient", calibration=None)
    assert g.inclination_before_deg == g.gradient_before_deg
    ami = geometric_estimate(windows[0], FS_HZ, delay="ami", dimension=4, calibration=None)
    assert ami.delay_rule.startswith("ami") and ami.dimension == 4
    fixed = geometric_estimate(windows[0], FS_HZ, delay=20, dimension=3, calibration=None)
    assert fixed.delay == 20 and fixed.delay_rule == "given"
    with pytest.raises(ConfigError, match="fitted on polynomial"):
        geometric_estimate(windows[0], FS_HZ, method="gradient")
    with pytest.raises(ConfigError):
        geometric_estimate(windows[0], FS_HZ, delay="acf")
    with pytest.raises(ConfigError):
        geometric_estimate(windows[0], FS_HZ, method="eyeball")
    with pytest.raises(ConfigError, match="fs_hz"):
        geometric_estimate(windows[0], 0.0)
    with pytest.raises(ConfigError, match="not found"):
        geometric_estimate(windows[0], FS_HZ, calibration="/nonexistent/cal.json")
    cal = load_calibration()
    assert geometric_estimate(windows[0], FS_HZ, calibration=cal).geometric_class == "soft"


@pytest.mark.parametrize(
    ("signal", "match"),
    [
        (np.full(2000, 3.0), "constant"),
        (np.r_[np.sin(np.arange(1999) / 10.0), np.nan], "NaN"),
        (np.sin(np.arange(10) / 2.0), "too short"),
        (np.sin(2 * np.pi * np.arange(200) / 95.0), "too short"),  # 2.1 periods
        (np.ones((40, 2)), "1-D"),
        (np.array(["a"] * 40), "numeric"),
    ],
)
def test_bad_input_raises_signal_error(signal, match):
    with pytest.raises(SignalError, match=match):
        geometric_estimate(signal, FS_HZ)


def test_dominant_period():
    t = np.arange(5000)
    assert dominant_period(np.sin(2 * np.pi * t / 87.3)) == pytest.approx(87.3, rel=2e-3)
    with pytest.raises(SignalError):
        dominant_period(np.zeros(100))


def test_sixty_seconds_at_2khz_in_well_under_a_second(windows):
    fs = 2000.0
    res = simulate_paper([26.0], n_samples=12000, fs_ratio=fs / PAPER_NATURAL_FREQUENCY_HZ)
    x = np.tile(res.accel[0], 10)  # 60 s; a periodic orbit, tiled
    geometric_estimate(x[:20000], fs)  # warm caches (calibration file)
    t0 = time.perf_counter()
    r = geometric_estimate(x, fs)
    elapsed = time.perf_counter() - t0
    assert r.contact_detected and r.n_orbits > 500
    assert elapsed < 1.5, f"{elapsed:.2f} s"
