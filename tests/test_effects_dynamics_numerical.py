"""Signatures of the numerically integrated dynamics effects on the acceleration.

Paper parameters (a = 1.9, w = 1.05, xi = 0.02, e = 2.8, beta = 26), sampled
at 500 points per natural period (fs = 500 f_n). Contact pulses are compared
on the first impact from x = 0, v = 5: the approach to the restraint is then
identical with and without the effect, so any difference is the effect's.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from stiffnet.effects.base import DynamicsEffect
from stiffnet.effects.dry_friction import STUCK, DryFriction
from stiffnet.effects.hertz_contact import HertzContact
from stiffnet.effects.restraint_mass import RestraintMass
from stiffnet.errors import ConfigError
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.numerical import simulate_numerical

A, W, XI, E, BETA = 1.9, 1.05, 0.02, 2.8, 26.0
H = 2 * np.pi / 500  # fs = 500 f_n


def simulate(
    effects: list[DynamicsEffect],
    n: int = 400,
    gap: float = E,
    x0: float = 0.0,
    v0: float = 5.0,
    h: float = H,
    n_transient: int = 0,
    substeps: int = 8,
) -> dict[str, np.ndarray]:
    """One trajectory (row 0 of the outputs) of the paper's parameter set."""
    batch = OscillatorBatch.single(BETA, gap, A, W, XI)
    params = [e.batch_params(1, np.random.default_rng(0)) for e in effects]
    hh = np.array([h])
    out = simulate_numerical(
        batch, effects, params, np.array([x0]), np.array([v0]), hh, n_transient, hh, n, substeps
    )
    return {k: v[0] for k, v in vars(out).items()}


def first_pulse(out: dict[str, np.ndarray]) -> slice:
    """Samples of the first contact pulse (contact force > 0)."""
    on = np.flatnonzero(out["contact_force"] > 0)
    assert on.size, "no contact"
    gaps = np.flatnonzero(np.diff(on) > 1)
    end = on[gaps[0]] if gaps.size else on[-1]
    return slice(on[0], end + 1)


def local_maxima(y: np.ndarray) -> int:
    return int(np.sum((y[1:-1] > y[:-2]) & (y[1:-1] >= y[2:])))


@pytest.mark.parametrize("cls", [HertzContact, RestraintMass, DryFriction])
def test_effects_are_numerical_dynamics_effects(cls: type[DynamicsEffect]) -> None:
    eff = cls()
    assert eff.kind == "dynamics" and not eff.closed_form
    assert eff.name == {"HertzContact": "hertz_contact", "RestraintMass": "restraint_mass"}.get(
        cls.__name__, "dry_friction"
    )
    rows = cls.parameter_table()
    assert rows and all(r["description"] and r["range"][0] <= r["default"] for r in rows)
    with pytest.raises(ConfigError):
        cls(**{rows[0]["name"]: rows[0]["range"][1] * 2 + 1})


# ---------------------------------------------------------------- Hertz contact


def test_hertz_secant_stiffness_is_beta_at_reference_penetration() -> None:
    batch = OscillatorBatch.single(BETA, E, A, W, XI)
    eff = HertzContact(reference_penetration=0.3)
    p = eff.batch_params(1, np.random.default_rng(0))
    for delta, secant in ((0.3, BETA), (0.075, BETA / 2), (1.2, 2 * BETA)):
        force = eff.elastic_contact(np.array([delta]), p, batch)[0]
        assert force / delta == pytest.approx(secant, rel=1e-12)


def test_hertz_onset_is_smooth_and_the_pulse_longer() -> None:
    linear = simulate([])
    hertz = simulate([HertzContact(reference_penetration=2.0)])
    pulses = {}
    for name, out in (("linear", linear), ("hertz", hertz)):
        pulse = first_pulse(out)
        x, accel = out["x"], out["accel"]
        assert x[pulse].max() - E < 2.0  # penetrations below delta_ref: Hertz is softer
        # contact force from the accelerometer signal: minus the spring and damper
        force = -(accel + 2 * XI * out["v"] + x)
        i = pulse.start
        onset = (i - 1) + (E - x[i - 1]) / (x[i] - x[i - 1])  # sample-time of x = e
        tau = (np.arange(i, i + 8) - onset) * H
        exponent = np.polyfit(np.log(tau), np.log(force[i : i + 8]), 1)[0]
        pulses[name] = (exponent, pulse.stop - pulse.start)
    # F ~ tau (a kink in the acceleration) for the linear restraint, tau^1.5 for Hertz
    assert pulses["linear"][0] == pytest.approx(1.0, abs=0.05)
    assert pulses["hertz"][0] == pytest.approx(1.5, abs=0.05)
    # softer below delta_ref: a longer contact (57 vs 47 samples)
    assert pulses["hertz"][1] > 1.15 * pulses["linear"][1]


# ---------------------------------------------------------------- restraint mass


def test_restraint_mass_rings_in_the_contact_pulse() -> None:
    massless = simulate([])
    pulse = first_pulse(massless)
    assert local_maxima(massless["contact_force"][pulse]) == 1
    assert local_maxima(-massless["accel"][pulse]) == 1
    # a beam about as stiff as the contact: the pulse is double-peaked
    ringing = simulate([RestraintMass(stiffness_ratio=30.0, mass_ratio=0.1)])
    pulse_r = first_pulse(ringing)
    assert local_maxima(ringing["contact_force"][pulse_r]) >= 2
    assert local_maxima(-ringing["accel"][pulse_r]) >= 2
    duration = pulse.stop - pulse.start
    assert (pulse_r.stop - pulse_r.start) > 1.15 * duration
    # defaults (a stiff, light beam): the series compliance lengthens the contact
    # and lowers the spike
    default = simulate([RestraintMass()])
    pulse_d = first_pulse(default)
    assert (pulse_d.stop - pulse_d.start) > 1.05 * duration
    assert -default["accel"][pulse_d].min() < 0.9 * -massless["accel"][pulse].min()


def test_restraint_is_pushed_and_the_massless_limit_is_approached() -> None:
    # a stiffer, heavier beam moves less: closer to the massless restraint
    massless = simulate([], n=150)
    errors = []
    for kappa in (100.0, 1000.0):
        out = simulate([RestraintMass(stiffness_ratio=kappa, mass_ratio=0.3)], n=150)
        errors.append(np.abs(out["accel"] - massless["accel"]).max())
    assert errors[1] < 0.25 * errors[0]


# ---------------------------------------------------------------- dry friction


def harmonic_balance_amplitude(mu_k: float) -> tuple[float, float]:
    """Amplitude and phase lag with friction replaced by its equivalent viscous damping."""
    f0 = A * W * W

    def residual(x: float) -> float:
        return x * x * ((1 - W * W) ** 2 + (2 * XI * W + 4 * mu_k / (np.pi * x)) ** 2) - f0**2

    x = brentq(residual, 1e-6, 100.0)
    return x, np.arctan2(2 * XI * W + 4 * mu_k / (np.pi * x), 1 - W * W)


@pytest.mark.parametrize("mu_k", [0.05, 0.2])
def test_friction_steps_the_acceleration_by_twice_its_force(mu_k: float) -> None:
    # far restraint: no impacts, a near-resonant steady state (started on it)
    amp, lag = harmonic_balance_amplitude(mu_k)
    out = simulate(
        [DryFriction(coefficient=mu_k)],
        n=300, gap=100.0, x0=-amp * np.sin(lag), v0=amp * W * np.cos(lag),
        h=2 * np.pi / (W * 100), n_transient=200, substeps=4,
    )  # fmt: skip
    v, accel = out["v"], out["accel"]
    jumps = []
    for sign in (1, -1):
        rev = np.flatnonzero((sign * v[:-1] > 0) & (sign * v[1:] <= 0))
        assert rev.size >= 2
        # the step is what a cubic extrapolation of the samples before it misses
        jumps += [
            sign * (accel[r + 1] - (3 * accel[r] - 3 * accel[r - 1] + accel[r - 2])) for r in rev
        ]
    np.testing.assert_allclose(jumps, 2 * mu_k, rtol=0.02)
    # less amplitude, as the equivalent-damping (harmonic balance) estimate says
    free = harmonic_balance_amplitude(0.0)[0]
    measured = (out["x"].max() - out["x"].min()) / 2
    assert measured == pytest.approx(amp, rel=0.01)
    assert measured < free - 4 * mu_k


def test_friction_sticks_and_the_mass_then_moves_with_the_table() -> None:
    eff = DryFriction(coefficient=1.5, static_ratio=1.3)
    h = 2 * np.pi / (W * 100)
    out = simulate([eff], n=300, gap=100.0, v0=0.0, h=h, n_transient=100, substeps=4)
    stuck = np.abs(out["v"]) < 1e-9
    assert 0.05 < stuck.mean() < 0.95
    t = out["t0"] + h * np.arange(300)
    # stuck: the absolute acceleration is the table's, the relative displacement flat
    table = -A * W * W * np.sin(W * t)
    np.testing.assert_allclose(out["accel"][stuck], table[stuck], atol=1e-9)
    runs = np.flatnonzero(np.diff(stuck.astype(int)) == 1)
    assert runs.size >= 2
    dx = np.abs(np.diff(out["x"]))[stuck[1:] & stuck[:-1]]
    assert dx.max() < 1e-9
    # the mode bookkeeping: stuck at a reversal only when the static level holds
    p = eff.batch_params(3, np.random.default_rng(0))
    mode = eff.next_mode(np.zeros(3), np.zeros(3), np.array([0.5, -2.5, 2.1]), np.zeros(3), p)
    np.testing.assert_array_equal(mode, [STUCK, -1.0, 0.0])
