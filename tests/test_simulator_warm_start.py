"""The numerical engine's warm start: the closed form settles the transient, RK4 finishes it.

Expectations: a warm start hands the closed form's exact state over at the right time (with
a numerical effect that is linear at its parameters the result is the closed form's to RK4
accuracy); with effects that are not, the warm and cold starts reach the same orbit (the
same impacts per forcing period, the acceleration's RMS and peak within the settle rule's
residual), and the orbit an independent integration (scipy's solve_ivp) reaches; the
default (cold) path is bitwise what the engine gives for the whole transient; a bad value
is one line.

Measured on the paper's parameters (beta 12, 26, 47; 100 samples per forcing period; 4
substeps; settle tolerance 1e-3; warm start 0.1): warm against cold, Hertz contact
(reference penetration 0.5) RMS 1.6e-4, peak 2.2e-3, x 1.5e-3 of its range; a heavy soft
restraint (mass ratio 1, stiffness ratio 10) 1.1e-6, 3.2e-5, 1.2e-5; dry friction 0.3
1.1e-6, 9.4e-6, 1.0e-5; impacts per forcing period the same in every row.
"""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.effects.base import DynamicsEffect
from stiffnet.effects.dry_friction import DryFriction
from stiffnet.effects.hertz_contact import HertzContact
from stiffnet.effects.restraint_mass import RestraintMass
from stiffnet.errors import ConfigError
from stiffnet.simulator import simulator as simulator_module
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.motion_cache import reuse_motion
from stiffnet.simulator.numerical import simulate_numerical
from stiffnet.simulator.simulator import WARM_MIN_PERIODS, Simulator

A, W, XI, E = 1.9, 1.05, 0.02, 2.8  # the paper's numerical parameter set (section 5.2)
BETAS = np.array([12.0, 26.0, 47.0])
PER_PERIOD = 100  # samples per forcing period
PERIODS = 12


def paper_batch() -> OscillatorBatch:
    n = BETAS.size
    return OscillatorBatch(BETAS, np.full(n, E), np.full(n, A), np.full(n, W), np.full(n, XI))


def run(effect: DynamicsEffect, params: dict[str, float], warm: float, **settings):
    batch = paper_batch()
    sim = Simulator([effect], warm_start=warm, **{"substeps": 4, **settings})
    p = {k: np.full(len(batch), v) for k, v in params.items()}
    return sim.simulate(
        batch, PER_PERIOD * W, PER_PERIOD * PERIODS, rng=5, effect_params={effect.name: p}
    )


@pytest.mark.parametrize(
    ("effect", "params"),
    [
        (HertzContact(), {"reference_penetration": 0.5}),
        (RestraintMass(), {"mass_ratio": 1.0, "stiffness_ratio": 10.0}),
        (DryFriction(), {"coefficient": 0.3}),
    ],
    ids=["hertz_contact", "restraint_mass", "dry_friction"],
)
def test_warm_start_reaches_the_cold_start_orbit(effect, params) -> None:
    cold, warm = run(effect, params, 0.0), run(effect, params, 0.1)
    # the same orbit: as many impacts per forcing period in every row (1, 1, 2/3 for the
    # Hertz contact; 2 for the heavy restraint, whose face bounces the mass twice; 1)
    np.testing.assert_array_equal(warm.impacts.sum(axis=1), cold.impacts.sum(axis=1))
    assert np.all(cold.impacts.sum(axis=1) > 0)
    # each start leaves a free oscillation of at most ~settle_tolerance (1e-3) of an
    # orbit-sized offset: the two differ by a few 1e-3 of the orbit at most
    rms = lambda r: np.sqrt(np.mean(r.clean_accel**2, axis=1))  # noqa: E731
    peak = lambda r: np.max(np.abs(r.clean_accel), axis=1)  # noqa: E731
    assert np.max(np.abs(rms(warm) / rms(cold) - 1)) < 2e-3
    assert np.max(np.abs(peak(warm) / peak(cold) - 1)) < 1e-2
    span = np.ptp(cold.x, axis=1)
    assert np.max(np.abs(warm.x - cold.x).max(axis=1) / span) < 5e-3


def test_handover_continues_the_closed_form_orbit(monkeypatch) -> None:
    """Dry friction with no friction is the linear model: after the handover RK4 carries the
    closed form's state on, at the right time and forcing phase (a time offset would show as
    a phase error of the order of the orbit)."""
    seen: dict = {}

    def spy(*args, **kwargs):
        seen.update(n_transient=args[6], t_start=np.asarray(kwargs["t_start"]))
        return simulate_numerical(*args, **kwargs)

    monkeypatch.setattr(simulator_module, "simulate_numerical", spy)
    warm = run(DryFriction(), {"coefficient": 0.0, "static_ratio": 1.0}, 0.1, substeps=8)
    batch = paper_batch()
    reference = Simulator([]).simulate(batch, PER_PERIOD * W, PER_PERIOD * PERIODS, rng=5)
    assert reference.engine == "closed_form" and warm.engine == "numerical"
    np.testing.assert_allclose(warm.t0, reference.t0, rtol=0, atol=1e-12)
    # RK4's own error at 8 substeps (6.6e-6 of the peak at beta 47, the same cold)
    peak = np.max(np.abs(reference.clean_accel))
    assert np.max(np.abs(warm.clean_accel - reference.clean_accel)) < 2e-5 * peak
    # the split: ln(0.1 / 1e-3) / xi = 230 model time before the first sample, the rest
    # (345 - 230) in closed form
    t_tr = Simulator([]).transient_time(batch)
    stretch = max(np.log(100.0) / XI, WARM_MIN_PERIODS * 2 * np.pi / W)
    np.testing.assert_allclose(seen["t_start"], t_tr - stretch)
    assert seen["t_start"].min() > 0.3 * t_tr.min()


def test_cold_start_is_the_whole_transient_bit_for_bit() -> None:
    """The default integrates the transient from t = 0 (the engine called as before)."""
    batch = paper_batch()
    eff = HertzContact()
    sim = Simulator([eff], substeps=4)
    assert sim.settings.warm_start == 0.0
    fs_ratio, n = PER_PERIOD * W, PER_PERIOD * 3
    got = sim.simulate(batch, fs_ratio, n, rng=5)
    rng = np.random.default_rng(5)
    x0 = rng.uniform(-1, 1, 3) * batch.amplitude
    v0 = rng.uniform(-1, 1, 3) * batch.amplitude * batch.omega
    p = eff.batch_params(3, rng)
    h = 2 * np.pi / np.full(3, fs_ratio)
    t_tr = sim.transient_time(batch)
    h_cap = np.minimum(2 * np.pi / 40, 1.5 / np.sqrt(1 + batch.beta))
    n_tr = int(np.ceil(np.max(t_tr / h_cap)))
    ref = simulate_numerical(batch, [eff], [p], x0, v0, (t_tr - h) / n_tr, n_tr, h, n, 4)
    np.testing.assert_array_equal(got.clean_accel, ref.accel)
    np.testing.assert_array_equal(got.x, ref.x)
    np.testing.assert_array_equal(got.impacts, ref.impacts)


def test_warm_and_cold_motions_are_kept_apart() -> None:
    """Inside ``reuse_motion`` a warm start does not serve a cold one (nor the reverse)."""
    params = {"reference_penetration": 0.5}
    with reuse_motion():
        cold = run(HertzContact(), params, 0.0, min_transient_periods=20.0)
        warm = run(HertzContact(), params, 0.1, min_transient_periods=20.0)
        again = run(HertzContact(), params, 0.1, min_transient_periods=20.0)
    assert not np.array_equal(cold.x, warm.x)
    np.testing.assert_array_equal(warm.x, again.x)


@pytest.mark.parametrize("bad", [-0.1, 1.5, float("nan")])
def test_bad_warm_start_is_one_line(bad: float) -> None:
    with pytest.raises(ConfigError) as err:
        Simulator([HertzContact()], warm_start=bad)
    msg = str(err.value)
    assert "warm_start" in msg and "\n" not in msg


def test_warm_start_leaves_the_closed_form_engine_alone() -> None:
    batch = paper_batch()
    cold = Simulator([]).simulate(batch, PER_PERIOD * W, 200, rng=5)
    warm = Simulator([], warm_start=0.1).simulate(batch, PER_PERIOD * W, 200, rng=5)
    np.testing.assert_array_equal(cold.accel, warm.accel)


def _hertz_solve_ivp(row: int, x0: float, v0: float, t: np.ndarray, delta_ref: float):
    """An independent integration of the Hertz oscillator from t = 0 (scipy's DOP853 on
    scalar right-hand sides; the force ``k_h delta^1.5`` is C1 at contact, so no event is
    needed at this tolerance): (x, absolute acceleration) at times ``t``."""
    from scipy.integrate import solve_ivp

    beta = float(BETAS[row])
    k_h = beta / np.sqrt(delta_ref)

    def force(x: float) -> float:
        d = x - E
        return k_h * d * np.sqrt(d) if d > 0 else 0.0

    def rhs(s: float, y: np.ndarray) -> list[float]:
        x, v = y
        return [v, A * W * W * np.sin(W * s) - 2 * XI * v - x - force(x)]

    sol = solve_ivp(
        rhs, (0.0, t[-1]), [x0, v0], method="DOP853", rtol=1e-10, atol=1e-10, t_eval=t,
        max_step=0.05,
    )  # fmt: skip
    x, v = sol.y
    return x, -(2 * XI * v + x + np.array([force(xi) for xi in x]))


def test_warm_start_reaches_an_independent_engines_orbit() -> None:
    """Hertz contact (beta 26): the warm start's recorded orbit is the one scipy's solve_ivp
    reaches from the same random initial state over the whole transient (another engine, the
    Hertz law written here), to the settle rule's residual; the cold start is solve_ivp's to
    integration accuracy (measured: x 2.7e-5 of its range, acceleration 2.2e-4 of its peak
    cold; 2.1e-3 and 1.3e-2 warm, the difference at the impact spikes; RMS 8e-4)."""
    batch = paper_batch()
    n, row = PER_PERIOD * 4, 1
    rng = np.random.default_rng(5)
    x0 = rng.uniform(-1, 1, 3) * batch.amplitude
    v0 = rng.uniform(-1, 1, 3) * batch.amplitude * batch.omega
    for warm_start, x_tol, a_tol in ((0.0, 2e-4, 2e-3), (0.1, 5e-3, 2.5e-2)):
        sim = Simulator([HertzContact()], warm_start=warm_start, substeps=4)
        got = sim.simulate(batch, PER_PERIOD * W, n, rng=5)
        t = got.t0[row] + np.arange(n) * 2 * np.pi / (PER_PERIOD * W)
        x, accel = _hertz_solve_ivp(row, x0[row], v0[row], t, 0.5)
        assert np.max(np.abs(got.x[row] - x)) < x_tol * np.ptp(x)
        assert np.max(np.abs(got.clean_accel[row] - accel)) < a_tol * np.max(np.abs(accel))
        rms = np.sqrt(np.mean(got.clean_accel[row] ** 2) / np.mean(accel**2))
        assert abs(rms - 1) < 2e-3
