"""Accuracy of the closed-form engine against independent solutions.

The engine is :func:`simulate_closed_form` (compiled); its numpy oracle
:func:`closed_form_reference` runs the single-impact cases too, and the two are
compared on random batches in ``test_simulator_oracle.py``.

* steady-state orbits through :class:`Simulator` against scipy's DOP853 with
  event location (:func:`reference_trajectory`), same initial state, same times;
* contact onset, grazing and release of single impacts against the analytic
  piecewise solution of the unforced oscillator (written out here, independently
  of the engine's own transition matrices);
* the linear steady state when the gap is never reached;
* reproducibility from a seed.

Model units throughout: time in 1 / (2 pi f_n), the mass at rest at x = 0 and
the restraint at x = e.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from reference_closed_form import closed_form_reference
from reference_solve_ivp import reference_trajectory
from scipy.optimize import brentq

from stiffnet.effects.contact_damping import ContactDamping
from stiffnet.effects.forcing_harmonics import ForcingHarmonics
from stiffnet.effects.gap_drift import GapDrift
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.compiled import simulate_closed_form
from stiffnet.simulator.result import EngineResult
from stiffnet.simulator.simulator import Simulator

PAPER = {"amplitude": 1.9, "omega": 1.05, "damping": 0.02, "gap": 2.8}  # section 5.2.1
FS_RATIO = 100.0  # fs / f_n: 100 samples per natural period
N_SAMPLES = 2000
# DOP853 checks the sign of the switching function only at its step ends: a
# shallow contact inside one free-flight step (~0.2 at rtol 1e-10) would be
# missed, so the reference bounds its steps.
REF_MAX_STEP = 0.1
BRENT_RTOL = 4 * np.finfo(float).eps  # the finest brentq accepts


def linear_amplitude(a: float, w: float, xi: float) -> float:
    """Steady amplitude of x for x'' + 2 xi x' + x = a w^2 sin(w t)."""
    return a * w * w / math.hypot(1 - w * w, 2 * xi * w)


def linear_steady_state(batch: OscillatorBatch, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x and v of the linear steady state at times ``t`` (rows broadcast against ``t``)."""
    a, w, xi = batch.amplitude, batch.omega, batch.damping
    amp = a * w * w / np.hypot(1 - w * w, 2 * xi * w)
    lag = np.arctan2(2 * xi * w, 1 - w * w)
    t = np.asarray(t, float)
    shape = (-1,) + (1,) * (t.ndim - 1) if t.ndim > 1 else (-1,)
    amp, w, lag = (q.reshape(shape) for q in (amp, w, lag))
    return amp * np.sin(w * t - lag), amp * w * np.cos(w * t - lag)


def damped(k: float, c: float, y0: float, v0: float, s: float) -> tuple[float, float]:
    """Exact y(s), y'(s) of y'' + c y' + k y = 0 (underdamped), from y(0)=y0, y'(0)=v0."""
    sig = 0.5 * c
    om = math.sqrt(k - sig * sig)
    dec = math.exp(-sig * s)
    cs, sn = math.cos(om * s), math.sin(om * s)
    y = dec * (y0 * cs + (v0 + sig * y0) / om * sn)
    v = dec * (v0 * cs - (k * y0 + sig * v0) / om * sn)
    return y, v


def first_root(fun: Callable[[float], float], s_max: float, n: int = 4000) -> float:
    """First sign change of ``fun`` on (0, s_max], to machine precision."""
    grid = np.linspace(0.0, s_max, n + 1)[1:]
    vals = np.array([fun(s) for s in grid])
    k = int(np.flatnonzero(np.sign(vals) != np.sign(vals[0]))[0])
    return brentq(fun, grid[k - 1], grid[k], xtol=1e-16, rtol=BRENT_RTOL, maxiter=200)


class SingleImpact:
    """Analytic piecewise solution of one impact of the unforced oscillator.

    From x(0) = 0, v(0) = v0 the mass flies freely (x'' + 2 xi x' + x = 0), enters
    contact at x = e, obeys x'' + (2 xi + c_c) x' + (1 + beta) x = beta e until the
    contact force beta (x - e) + c_c v reaches zero, then flies freely again.
    """

    def __init__(self, beta: float, xi: float, cc: float, gap: float, v0: float) -> None:
        self.beta, self.xi, self.cc, self.gap = beta, xi, cc, gap
        self.k_c, self.c_c = 1.0 + beta, 2 * xi + cc
        self.x_eq = beta * gap / (1.0 + beta)  # static equilibrium in contact
        self.v0 = v0
        self.t_in = first_root(lambda s: self.free(0.0, v0, s)[0] - gap, math.pi)
        self.v_in = self.free(0.0, v0, self.t_in)[1]
        self.t_out = self.t_in + first_root(
            lambda s: self.contact_force(*self.in_contact(s)), 2 * math.pi / math.sqrt(self.k_c)
        )
        self.x_out, self.v_out = self.in_contact(self.t_out - self.t_in)

    def free(self, x0: float, v0: float, s: float) -> tuple[float, float]:
        return damped(1.0, 2 * self.xi, x0, v0, s)

    def in_contact(self, s: float) -> tuple[float, float]:
        """State at t_in + s along the contact solution."""
        y, v = damped(self.k_c, self.c_c, self.gap - self.x_eq, self.v_in, s)
        return y + self.x_eq, v

    def contact_force(self, x: float, v: float) -> float:
        # its first zero after entry is the release (undamped: x back at e)
        return self.beta * (x - self.gap) + self.cc * v

    def state(self, t: float) -> tuple[float, float]:
        if t < self.t_in:
            return self.free(0.0, self.v0, t)
        if t < self.t_out:
            return self.in_contact(t - self.t_in)
        return self.free(self.x_out, self.v_out, t - self.t_out)


SOLVERS = pytest.mark.parametrize(
    "solver", [simulate_closed_form, closed_form_reference], ids=["engine", "oracle"]
)


def run_unforced(
    beta: float,
    xi: float,
    gap: float,
    v0: float,
    h: float,
    n: int,
    damping_ratio: float = 0.0,
    solver: Callable[..., EngineResult] = simulate_closed_form,
) -> EngineResult:
    """``solver`` from x=0, v=v0 at t=0, no forcing, samples at t = h, 2h, ..."""
    batch = OscillatorBatch.single(beta, gap, 0.0, 1.0, xi)
    sim = Simulator([ContactDamping(damping_ratio=damping_ratio)])
    model = sim.linear_model(
        batch, {"contact_damping": {"damping_ratio": np.array([damping_ratio])}}
    )
    hh = np.array([h])
    return solver(model, np.zeros(1), np.array([v0]), hh, hh, n)


# ------------------------------------------------------------ steady-state orbits

CASES = {
    # name: (beta, gap, a, w, xi)
    "paper_beta12": (12.0, PAPER["gap"], PAPER["amplitude"], PAPER["omega"], PAPER["damping"]),
    "paper_beta47": (47.0, PAPER["gap"], PAPER["amplitude"], PAPER["omega"], PAPER["damping"]),
    "hard_beta100": (100.0, PAPER["gap"], PAPER["amplitude"], PAPER["omega"], PAPER["damping"]),
    "zero_gap": (20.0, 0.0, 0.5, 0.9, 0.03),
    # the gap 1% of the linear amplitude inside it: shallow, slow impacts
    "grazing": (50.0, linear_amplitude(1.0, 0.8, 0.05) - 0.01, 1.0, 0.8, 0.05),
}


def compare_with_reference(sim: Simulator, batch: OscillatorBatch) -> list[tuple[float, int]]:
    """Max |accel error| / peak |accel| and the impact count of each row."""
    # Start both on the linear steady state: an explicit, shared initial state.
    x0, v0 = linear_steady_state(batch, np.zeros(len(batch)))
    res = sim.simulate(batch, FS_RATIO, N_SAMPLES, x0=x0, v0=v0)
    model = sim.linear_model(batch, res.effect_params)
    out = []
    for i in range(len(batch)):
        t = res.t0[i] + np.arange(N_SAMPLES) * 2 * np.pi / FS_RATIO
        ref = reference_trajectory(model, i, x0[i], v0[i], t, rtol=1e-10, max_step=REF_MAX_STEP)
        peak = np.abs(ref["accel"]).max()
        out.append((np.abs(res.clean_accel[i] - ref["accel"]).max() / peak, res.impacts[i].sum()))
    return out


def test_steady_orbits_match_dop853_reference() -> None:
    batch = OscillatorBatch(*(np.array(col) for col in zip(*CASES.values(), strict=True)))
    # free oscillations decay to 1% (~230-460 time units), then ~20 forcing periods
    # are recorded; both engines integrate all of it from the same state at t = 0
    sim = Simulator(min_transient_periods=20, settle_tolerance=1e-2)
    for name, (err, impacts) in zip(CASES, compare_with_reference(sim, batch), strict=True):
        assert impacts > 0, name  # every case impacts: the events are exercised
        assert err <= 1e-6, f"{name}: max error {err:.2e} of the peak acceleration"


def test_orbit_with_closed_form_effects_matches_reference() -> None:
    # The reference takes forcing/gap sinusoids and contact damping from the same
    # LinearModel; a drift period of 20 natural periods changes the gap visibly.
    batch = OscillatorBatch.single(47.0, **PAPER)
    effects = [
        ContactDamping(damping_ratio=0.1),
        ForcingHarmonics(second=0.05, third=0.02, phase_second=0.5, phase_third=-1.0),
        GapDrift(amplitude=0.2, period=20.0, phase=0.3),
    ]
    sim = Simulator(effects, min_transient_periods=20, settle_tolerance=1e-2)
    assert sim.engine == "closed_form"
    [(err, impacts)] = compare_with_reference(sim, batch)
    assert impacts > 0
    assert err <= 1e-6


# ------------------------------------------------------------------ event location


@SOLVERS
def test_contact_onset_is_located_between_samples(solver) -> None:
    beta, xi, gap, v0 = 50.0, 0.02, 0.6, 1.0
    h = 2 * np.pi / FS_RATIO
    exact = SingleImpact(beta, xi, 0.0, gap, v0)
    # the onset falls well inside a sampling interval, not on the grid
    frac = exact.t_in / h % 1.0
    assert 0.1 < frac < 0.9
    out = run_unforced(beta, xi, gap, v0, h, 40, solver=solver)
    t = out.t0[0] + np.arange(40) * h
    first = int(np.flatnonzero(out.contact_force[0] > 0)[0])
    assert t[first - 1] < exact.t_in < t[first]
    assert out.impacts[0].sum() == 1 and out.impacts[0, first] == 1
    xm, vm = out.x[0, first], out.v[0, first]

    # The engine's own onset: follow its contact state back to x = e. (Both the
    # free and the contact solution pass through the onset state, so this recovers
    # the time it switched, to round-off.)
    def penetration_back(s: float) -> float:
        y, _ = damped(exact.k_c, exact.c_c, xm - exact.x_eq, vm, -s)
        return y + exact.x_eq - gap

    t_onset = t[first] - brentq(penetration_back, 0.0, h, xtol=1e-16, rtol=BRENT_RTOL)
    assert abs(t_onset - exact.t_in) < 1e-12
    # the state just after onset is the exact contact solution ...
    for n in range(first, first + 3):
        x_ex, v_ex = exact.state(t[n])
        assert abs(out.x[0, n] - x_ex) < 1e-12
        assert abs(out.v[0, n] - v_ex) < 1e-12
    # ... which switching on the grid (at either sample) would miss by far more
    x_late = exact.free(0.0, v0, t[first])[0]
    x_prev, v_prev = exact.free(0.0, v0, t[first - 1])
    x_early = damped(exact.k_c, exact.c_c, x_prev - exact.x_eq, v_prev, h)[0] + exact.x_eq
    x_true = exact.state(t[first])[0]
    assert min(abs(x_late - x_true), abs(x_early - x_true)) > 1e-6
    # the DOP853 reference agrees on the samples around the onset
    model = Simulator().linear_model(OscillatorBatch.single(beta, gap, 0.0, 1.0, xi), {})
    ref = reference_trajectory(model, 0, 0.0, v0, t, max_step=REF_MAX_STEP)
    np.testing.assert_allclose(ref["x"][first - 2 : first + 3], out.x[0, first - 2 : first + 3],
                               atol=1e-9)  # fmt: skip


@SOLVERS
@pytest.mark.parametrize("depth", [1e-6, -1e-6])
def test_grazing_contact_inside_one_interval_is_detected(depth: float, solver) -> None:
    beta, xi, v0 = 50.0, 0.02, 1.0
    h = 2 * np.pi / FS_RATIO
    wd = math.sqrt(1 - xi * xi)
    t_peak = math.atan2(wd, xi) / wd  # first maximum of the free flight
    x_peak = math.exp(-xi * t_peak) * v0 / wd * math.sin(wd * t_peak)
    gap = x_peak - depth  # penetration of `depth` (none when negative)
    n = 40
    out = run_unforced(beta, xi, gap, v0, h, n, solver=solver)
    t = out.t0[0] + np.arange(n) * h
    assert not np.any(out.contact_force > 0)  # no sample is in contact
    if depth < 0:
        assert out.impacts.sum() == 0
        return
    exact = SingleImpact(beta, xi, 0.0, gap, v0)
    # contact lasts ~2 sqrt(2 depth / x_peak) ~ 3e-3, far inside one interval of 0.063
    assert 0 < exact.t_out - exact.t_in < 0.1 * h
    k = int(np.searchsorted(t, exact.t_in))
    assert t[k - 1] < exact.t_in and exact.t_out < t[k]
    counts = out.impacts[0]
    assert counts.sum() == 1 and counts[k] == 1, f"one graze, counted {counts.tolist()}"
    # the graze changed the velocity by ~1e-7; the engine carries it exactly
    x_ex, v_ex = exact.state(t[-1])
    x_miss, v_miss = exact.free(0.0, v0, t[-1])  # had the graze gone unnoticed
    assert abs(v_ex - v_miss) > 1e-8
    assert abs(out.x[0, -1] - x_ex) < 1e-13
    assert abs(out.v[0, -1] - v_ex) < 1e-13


@SOLVERS
def test_damped_contact_never_pulls_and_releases_before_gap(solver) -> None:
    beta, xi, gap, v0, zeta = 50.0, 0.02, 0.6, 1.0, 0.3
    cc = 2 * zeta * math.sqrt(beta)
    h = 2 * np.pi / 400  # fine sampling: ~28 samples per contact
    n = 200
    out = run_unforced(beta, xi, gap, v0, h, n, damping_ratio=zeta, solver=solver)
    t = out.t0[0] + np.arange(n) * h
    x, v, force = out.x[0], out.v[0], out.contact_force[0]
    exact = SingleImpact(beta, xi, cc, gap, v0)
    # release where the force reaches zero, the penetration still positive
    assert exact.x_out - gap > 1e-3
    # the engine follows the exact piecewise solution through onset and release
    states = np.array([exact.state(tt) for tt in t])
    np.testing.assert_allclose(x, states[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(v, states[:, 1], rtol=0, atol=1e-12)
    assert force.min() >= 0.0
    in_contact = force > 0
    assert np.all(in_contact == ((t > exact.t_in) & (t < exact.t_out)))
    # force at a sample in contact: spring plus damper, jumping to ~cc*v at onset
    np.testing.assert_allclose(force[in_contact], beta * (x - gap)[in_contact] + cc * v[in_contact],
                               rtol=1e-12)  # fmt: skip
    assert force[in_contact][0] > 0.5 * cc * exact.v_in
    # after release the mass is still beyond e for a while: a linear spring-dashpot
    # would pull it there, the restraint does not
    after = ~in_contact & (t > exact.t_in) & (x > gap)
    assert after.sum() >= 2
    assert np.all(beta * (x - gap)[after] + cc * v[after] < 0)
    assert np.all(force[after] == 0)
    assert out.impacts[0].sum() == 1


# ------------------------------------------------------------------ physical sanity


def test_no_contact_gives_linear_steady_state() -> None:
    batch = OscillatorBatch(
        beta=np.array([47.0, 12.0, 100.0]),
        gap=np.array([50.0, 100.0, 30.0]),  # beyond the linear amplitudes (<= 21)
        amplitude=np.array([1.9, 1.0, 0.5]),
        omega=np.array([1.05, 0.8, 1.2]),
        damping=np.array([0.02, 0.05, 0.01]),
    )
    sim = Simulator(min_transient_periods=5, settle_tolerance=0.5)
    # started on the steady state it stays there, to round-off
    x0, v0 = linear_steady_state(batch, np.zeros(3))
    res = sim.simulate(batch, FS_RATIO, 1000, x0=x0, v0=v0)
    t = res.t0[:, None] + np.arange(1000) * 2 * np.pi / FS_RATIO
    xs, vs = linear_steady_state(batch, t)
    amp = np.array([linear_amplitude(a, w, z) for a, w, z in
                    zip(batch.amplitude, batch.omega, batch.damping, strict=True)])  # fmt: skip
    assert np.abs(res.x - xs).max() < 1e-10 * amp.max()  # round-off over ~1000 steps
    np.testing.assert_allclose(res.x.max(axis=1), amp, rtol=1e-3)  # sampled peaks
    # the accelerometer on the mass: spring and damper forces only
    accel = -(xs + 2 * batch.damping[:, None] * vs)
    np.testing.assert_allclose(res.clean_accel, accel, rtol=0, atol=1e-11 * amp.max())
    assert res.impacts.sum() == 0 and not np.any(res.contact_force)
    # from a random start the transient decays to the same orbit
    sim = Simulator(min_transient_periods=5, settle_tolerance=1e-6)
    res = sim.simulate(batch, FS_RATIO, 1000, rng=3)
    xs, _ = linear_steady_state(batch, res.t0[:, None] + np.arange(1000) * 2 * np.pi / FS_RATIO)
    assert np.all(np.abs(res.x - xs).max(axis=1) < 1e-5 * amp)
    assert res.impacts.sum() == 0


# ------------------------------------------------------------------ reproducibility


def test_seed_reproducibility() -> None:
    batch = OscillatorBatch(
        beta=np.array([12.0, 47.0]), gap=np.array([2.8, 1.0]), amplitude=np.array([1.9, 1.0]),
        omega=np.array([1.05, 0.95]), damping=np.array([0.02, 0.03]),
    )  # fmt: skip
    # a short transient keeps the initial conditions visible in the samples
    sim = Simulator([ContactDamping(damping_ratio=[0.05, 0.3])], min_transient_periods=1,
                    settle_tolerance=0.9)  # fmt: skip
    a = sim.simulate(batch, 50.0, 300, noise=0.05, rng=7)
    b = sim.simulate(batch, 50.0, 300, noise=0.05, rng=7)
    for name in ("accel", "clean_accel", "x", "v", "contact_force", "impacts", "t0"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.array_equal(a.effect_params["contact_damping"]["damping_ratio"],
                          b.effect_params["contact_damping"]["damping_ratio"])  # fmt: skip
    c = sim.simulate(batch, 50.0, 300, noise=0.05, rng=8)
    assert np.all(np.abs(c.x[:, 0] - a.x[:, 0]) > 1e-3)  # other initial conditions
    assert not np.array_equal(c.effect_params["contact_damping"]["damping_ratio"],
                              a.effect_params["contact_damping"]["damping_ratio"])  # fmt: skip
    # given the initial state and fixed parameters, the seed only draws the noise
    fixed = Simulator(min_transient_periods=1, settle_tolerance=0.9)
    x0, v0 = np.array([0.3, -0.2]), np.array([0.1, 0.5])
    d = fixed.simulate(batch, 50.0, 300, x0=x0, v0=v0, noise=0.05, rng=1)
    e = fixed.simulate(batch, 50.0, 300, x0=x0, v0=v0, noise=0.05, rng=2)
    assert np.array_equal(d.clean_accel, e.clean_accel)
    assert not np.array_equal(d.accel, e.accel)


def test_contact_under_way_at_first_sample_is_not_an_impact():
    """An impact counts once, at the first sample after its onset, not again when a
    record starts during a contact (the record's first segment then starts in
    contact: with samples sparser than the contact step it falls inside the
    first sampling interval)."""
    batch = OscillatorBatch.single(20.0, 0.0, 0.5, 1.0, 0.02)
    model = Simulator().linear_model(batch, {})
    x0, v0 = np.array([0.1]), np.array([0.0])
    fine = np.array([2 * np.pi / 400])
    full = simulate_closed_form(model, x0, v0, fine, fine, 400)
    on = int(np.flatnonzero(full.contact_force[0] > 0)[0])
    t_on = fine[0] * (on + 1)
    sparse = np.array([2 * np.pi / 16])  # longer than the contact step 1/sqrt(21)
    late = simulate_closed_form(model, x0, v0, np.array([t_on + 0.3]), sparse, 4)
    assert late.contact_force[0, 0] > 0  # the record starts inside the contact
    assert late.impacts[0, 0] == 0
