"""Signatures of the closed-form dynamics effects, a user-written effect and the registry.

Each test compares a run with the effect against the same run without it, on
quantities the effect should (and only it should) change: the coefficient of
restitution of one impact, spectral lines of the forcing, the impact rate over
a drift period, a static offset.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from stiffnet.effects.base import Effect
from stiffnet.effects.contact_damping import ContactDamping
from stiffnet.effects.forcing_harmonics import ForcingHarmonics
from stiffnet.effects.gap_drift import GapDrift
from stiffnet.effects.registry import CANONICAL, build_effect, parse_effect_option
from stiffnet.errors import ConfigError
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.compiled import simulate_closed_form
from stiffnet.simulator.simulator import Simulator


def free_flight(x0: float, v0: float, xi: float, s: float) -> tuple[float, float]:
    """Exact x(s), v(s) of x'' + 2 xi x' + x = 0 (negative s runs backwards)."""
    wd = math.sqrt(1 - xi * xi)
    dec = math.exp(-xi * s)
    cs, sn = math.cos(wd * s), math.sin(wd * s)
    return (
        dec * (x0 * cs + (v0 + xi * x0) / wd * sn),
        dec * (v0 * cs - (x0 + xi * v0) / wd * sn),
    )


def transfer(w: np.ndarray | float, xi: float) -> np.ndarray | complex:
    """Absolute acceleration of the mass per unit forcing at frequency ``w``.

    x'' + 2 xi x' + x = F e^{iwt} gives x = F / (1 - w^2 + 2i xi w), and the
    accelerometer reads -(x + 2 xi x').
    """
    return -(1 + 2j * xi * w) / (1 - w * w + 2j * xi * w)


def steady_start(batch: OscillatorBatch) -> tuple[np.ndarray, np.ndarray]:
    """x, v at t = 0 on the linear steady state of the fundamental forcing."""
    a, w, xi = batch.amplitude, batch.omega, batch.damping
    amp = a * w * w / np.hypot(1 - w * w, 2 * xi * w)
    lag = np.arctan2(2 * xi * w, 1 - w * w)
    return -amp * np.sin(lag), amp * w * np.cos(lag)


# ------------------------------------------------------------------ contact damping


def single_impact(damping_ratio: float, n: int = 500) -> dict[str, float]:
    """One impact of the unforced oscillator (beta 50, gap 0.6), from x=0, v=1.

    Sampled at fs = 2000 f_n (~130 samples per contact). Returns the coefficient
    of restitution (speeds at x = e on the way in and out), the peak force and
    where in the pulse it is, and the force at the first and last contact sample.
    """
    beta, xi, gap, v0 = 50.0, 0.02, 0.6, 1.0
    batch = OscillatorBatch.single(beta, gap, 0.0, 1.0, xi)
    sim = Simulator([ContactDamping(damping_ratio=damping_ratio)])
    params = {"contact_damping": {"damping_ratio": np.array([damping_ratio])}}
    h = np.array([2 * np.pi / 2000])
    out = simulate_closed_form(
        sim.linear_model(batch, params), np.zeros(1), np.array([v0]), h, h, n
    )
    x, v, force = out.x[0], out.v[0], out.contact_force[0]
    assert force.min() >= 0 and out.impacts.sum() == 1
    contact = np.flatnonzero(force > 0)
    first, last = contact[0], contact[-1]
    # in and out speeds where the mass crosses x = e, from free-flight samples
    # followed exactly (forwards from the start, backwards from after release)
    t_in = brentq(lambda s: free_flight(0.0, v0, xi, s)[0] - gap, 0.0, math.pi / 2)
    v_in = free_flight(0.0, v0, xi, t_in)[1]
    m = int(np.flatnonzero((np.arange(n) > last) & (x < gap))[0])
    back = brentq(lambda s: free_flight(x[m], v[m], xi, -s)[0] - gap, 0.0, (m - last) * h[0])
    v_out = free_flight(x[m], v[m], xi, -back)[1]
    return {
        "restitution": -v_out / v_in,
        "peak": force.max(),
        "peak_at": (np.argmax(force) - first) / (last - first),
        "first": force[first],
        "last": force[last],
        "v_in": v_in,
        "spike": np.abs(out.accel[0]).max(),
    }


def test_contact_damping_dissipates_energy_at_each_impact() -> None:
    ratios = (0.0, 0.05, 0.1, 0.2)
    runs = {z: single_impact(z) for z in ratios}
    cor = [runs[z]["restitution"] for z in ratios]
    # elastic contact: only the primary damper's loss during ~0.4 of contact
    assert 0.98 < cor[0] < 1.0
    assert all(a > b + 0.05 for a, b in zip(cor[:-1], cor[1:], strict=True)), cor
    assert cor[2] < 0.85  # zeta_c = 0.1 loses over a quarter of the impact energy
    # lower spike for the same approach speed, in force and in acceleration
    peaks = [runs[z]["peak"] for z in ratios]
    assert all(a > b for a, b in zip(peaks[:-1], peaks[1:], strict=True)), peaks
    assert runs[0.1]["spike"] < 0.95 * runs[0.0]["spike"]


def test_contact_damping_pulse_is_asymmetric() -> None:
    elastic, damped = single_impact(0.0), single_impact(0.2)
    # elastic: a half-sine-like pulse, peak in the middle, ~0 at both ends
    assert elastic["peak_at"] == pytest.approx(0.5, abs=0.02)
    assert max(elastic["first"], elastic["last"]) < 0.01 * elastic["peak"]
    # damped: the force jumps to ~c_c v_in at onset, peaks early, ends at 0
    cc = 2 * 0.2 * math.sqrt(50.0)
    assert damped["first"] == pytest.approx(cc * damped["v_in"], rel=0.05)
    assert damped["peak_at"] < 0.4
    assert damped["last"] < 0.05 * damped["first"]


# ---------------------------------------------------------------- forcing harmonics


def harmonic_lines(effects: list[Effect]) -> np.ndarray:
    """Complex amplitudes C_k (signal Re C_k e^{i k w t}) of the acceleration at w, 2w, 3w.

    No contact (gap 100); the record spans exactly 32 forcing periods, so each
    harmonic falls on an FFT bin.
    """
    batch = OscillatorBatch.single(20.0, 100.0, 1.0, 0.9, 0.05)
    w = batch.omega[0]
    per_period, periods = 64, 32
    sim = Simulator(effects, settle_tolerance=1e-9)
    x0, v0 = steady_start(batch)
    res = sim.simulate(batch, per_period * w, per_period * periods, x0=x0, v0=v0)
    assert res.impacts.sum() == 0
    spec = np.fft.fft(res.clean_accel[0])
    k = np.arange(1, 4)
    return 2 * spec[k * periods] / spec.size * np.exp(-1j * k * w * res.t0[0])


def test_forcing_harmonics_add_lines_with_linear_response() -> None:
    a, w, xi = 1.0, 0.9, 0.05
    h2, h3, ph2, ph3 = 0.05, 0.02, 0.7, -0.4
    eff = ForcingHarmonics(second=h2, third=h3, phase_second=ph2, phase_third=ph3)
    lines = harmonic_lines([eff])
    # forcing a w^2 h_k sin(k w t + phi_k) = Re(-i a w^2 h_k e^{i phi_k} e^{i k w t})
    forcing = -1j * a * w * w * np.array([1.0, h2 * np.exp(1j * ph2), h3 * np.exp(1j * ph3)])
    expected = forcing * transfer(np.array([1, 2, 3]) * w, xi)
    np.testing.assert_allclose(lines, expected, rtol=0, atol=1e-7 * abs(expected[0]))
    # the ratios the table's distortion produces on the mass, not h_2 and h_3 themselves
    ratio2 = h2 * abs(transfer(2 * w, xi) / transfer(w, xi))
    ratio3 = h3 * abs(transfer(3 * w, xi) / transfer(w, xi))
    assert abs(lines[1] / lines[0]) == pytest.approx(ratio2, rel=1e-6)
    assert abs(lines[2] / lines[0]) == pytest.approx(ratio3, rel=1e-6)
    assert ratio2 < 0.5 * h2  # above resonance the mass filters the harmonics
    # without the effect: the same fundamental, no harmonics
    plain = harmonic_lines([])
    assert plain[0] == pytest.approx(lines[0], rel=1e-9)
    assert np.all(np.abs(plain[1:]) < 1e-9 * abs(plain[0]))


# ------------------------------------------------------------------------ gap drift


def test_gap_drift_switches_impacts_on_and_off_over_its_period() -> None:
    beta, a, w, xi = 30.0, 0.5, 0.95, 0.05
    amp = a * w * w / math.hypot(1 - w * w, 2 * xi * w)  # 3.3, linear amplitude
    batch = OscillatorBatch.single(beta, amp + 0.3, a, w, xi)  # just out of reach
    period, fs_ratio = 30.0, 50.0  # drift period in natural periods; fs / f_n
    n = int(period * fs_ratio)  # the recording spans one drift period (~28 forcing periods)
    drift = GapDrift(amplitude=1.0, period=period, phase=0.0)
    res = Simulator([drift]).simulate(batch, fs_ratio, n, rng=0)
    steady = Simulator().simulate(batch, fs_ratio, n, rng=0)
    assert steady.impacts.sum() == 0
    t = res.t0[0] + np.arange(n) * 2 * np.pi / fs_ratio
    gap = batch.gap[0] + 1.0 * np.sin(t / period)  # e(t)
    narrow = gap < batch.gap[0]
    assert narrow.sum() == pytest.approx(n / 2, abs=2)
    impacts = res.impacts[0]
    # impacts only while the restraint has come closer, over many forcing periods
    assert impacts[~narrow].sum() == 0
    assert impacts[narrow].sum() >= 6
    # the restraint moves: the force acts on the penetration x - e(t)
    c = res.contact_force[0] > 0
    np.testing.assert_allclose(res.contact_force[0, c], beta * (res.x[0, c] - gap[c]), rtol=1e-9)
    assert np.all(res.x[0, c] < batch.gap[0])  # contact below the nominal gap


# ---------------------------------------------------------------- user-written effect


@pytest.fixture
def user_module(monkeypatch: pytest.MonkeyPatch) -> str:
    """Load ``tests/user_effects.py`` as a plugin (effect names never import from sys.path)."""
    from pathlib import Path

    from stiffnet.effects.registry import register_plugin

    return register_plugin(Path(__file__).parent / "user_effects.py")


def test_user_dynamics_effect_runs_in_closed_form(user_module: str) -> None:
    preload = build_effect(f"{user_module}:ConstantPreload", {"force": 0.4})
    assert preload.name == "constant_preload" and preload.closed_form
    a, w, xi = 1.0, 0.9, 0.05
    amp = a * w * w / math.hypot(1 - w * w, 2 * xi * w)
    # the preload pushes a free mass 0.4 towards a restraint 0.2 out of its reach
    batch = OscillatorBatch(
        beta=np.array([20.0, 20.0]), gap=np.array([100.0, amp + 0.2]),
        amplitude=np.array([a, a]), omega=np.array([w, w]), damping=np.array([xi, xi]),
    )  # fmt: skip
    periods, per_period = 20, 64
    kwargs = {"fs_ratio": per_period * w, "n_samples": periods * per_period, "rng": 0}
    sim = Simulator([preload], settle_tolerance=1e-6)
    assert sim.engine == "closed_form"
    loaded = sim.simulate(batch, **kwargs)
    free = Simulator(settle_tolerance=1e-6).simulate(batch, **kwargs)
    # no contact: a static sag of `force`, read by the accelerometer as -force
    assert loaded.x[0].mean() - free.x[0].mean() == pytest.approx(0.4, abs=1e-7)
    assert loaded.clean_accel[0].mean() == pytest.approx(-0.4, abs=1e-7)
    np.testing.assert_allclose(loaded.x[0] - free.x[0], 0.4, atol=1e-6)
    # near the restraint: the preload closes the gap
    assert free.impacts[1].sum() == 0
    assert abs(loaded.impacts[1].sum() - periods) <= 1  # one impact per forcing period
    assert loaded.impacts[1].max() == 1


def test_user_measurement_effect_and_its_validation(user_module: str) -> None:
    gain = build_effect(f"{user_module}:Gain", {"gain": 2.5})
    batch = OscillatorBatch.single(47.0, 2.8, 1.9, 1.05, 0.02)
    res = Simulator([gain], min_transient_periods=5).simulate(batch, 100.0, 500, rng=1)
    assert res.impacts.sum() > 0
    np.testing.assert_allclose(res.accel, 2.5 * res.clean_accel, rtol=1e-15)
    with pytest.raises(ConfigError, match=r"gain=20.0 is outside the allowed range \[0.1, 10.0\]"):
        build_effect(f"{user_module}:Gain", {"gain": 20.0})
    with pytest.raises(ConfigError, match="not a DynamicsEffect or MeasurementEffect"):
        build_effect(f"{user_module}:steady_start_missing")  # not a class of the module


# ------------------------------------------------------------------------- registry


def test_unknown_effect_names_the_known_ones() -> None:
    with pytest.raises(ConfigError) as err:
        build_effect("contact_dampening")
    msg = str(err.value)
    assert "'contact_dampening'" in msg
    for name in CANONICAL:
        assert name in msg
    with pytest.raises(ConfigError, match="'no_such_module:Effect' is not a registered"):
        build_effect("no_such_module:Effect")


@pytest.mark.parametrize(
    ("params", "pattern"),
    [
        ({"damping_ratio": 1.5}, r"damping_ratio=1.5 is outside the allowed range \[0.0, 1.0\]"),
        ({"damping_ratio": [0.1, 2.0]}, r"damping_ratio=2.0 is outside .* \[0.0, 1.0\]"),
        ({"damping_ratio": [0.3, 0.1]}, r"damping_ratio: a range must be \[low, high\]"),
        ({"damping": 0.1}, r"damping"),  # unknown field: named
    ],
)
def test_bad_parameters_name_field_and_range(params: dict, pattern: str) -> None:
    with pytest.raises(ConfigError, match=pattern) as err:
        build_effect("contact_damping", params)
    assert str(err.value).startswith("effect contact_damping")


def test_parse_effect_option() -> None:
    name, params = parse_effect_option("adc:bits=12,full_scale=5..10")
    assert (name, params) == ("adc", {"bits": 12.0, "full_scale": [5.0, 10.0]})
    adc = build_effect(name, params)
    draws = adc.batch_params(1000, np.random.default_rng(0))
    assert np.all(draws["bits"] == 12)
    assert 5 <= draws["full_scale"].min() < 5.1 and 9.9 < draws["full_scale"].max() <= 10
    assert parse_effect_option("gap_drift") == ("gap_drift", {})
    assert parse_effect_option("user_effects:ConstantPreload:force=-0.5") == (
        "user_effects:ConstantPreload",
        {"force": -0.5},
    )
    assert parse_effect_option("user_effects:ConstantPreload") == (
        "user_effects:ConstantPreload",
        {},
    )
    with pytest.raises(ConfigError, match="is not a number"):
        parse_effect_option("adc:bits=twelve")
    with pytest.raises(ConfigError, match=r"expected NAME\[:key=value"):
        parse_effect_option("adc:bits=12,full_scale")
