"""The numerical engine's events located by Newton steps from a Hermite guess.

Where the contact's root function is the penetration (no contact damping), or an effect's
event function has a rate it gives (``event_rate``: dry friction's slip, whose function is
the velocity), the rate is known at both ends of the substep and at every partial step, so
the locator starts at the root of the cubic Hermite interpolant and takes Newton steps
(:func:`events._newton`) instead of the secant's. Expectation: the same event (within the
secant's tolerance of the root of the same function), at the analytic contact time of a
free flight (the slip reversal of a friction-braked one) to RK4's accuracy, the same
trajectory to round-off, in fewer partial steps; and the locator keeps the secant's
contract (far side of the root, within the tolerance) on hard functions.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from stiffnet.effects.dry_friction import STUCK, DryFriction
from stiffnet.effects.hertz_contact import HertzContact
from stiffnet.effects.restraint_mass import RestraintMass
from stiffnet.simulator import events as ev
from stiffnet.simulator import numerical as nm
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.numerical import simulate_numerical
from tests.test_simulator_numerical import _rm

XI, GAP, V0 = 0.05, 0.5, 1.0
H, SUB = 0.05, 2  # sample step and substeps: the contact falls inside a substep


def _free_flight_contact_time() -> float:
    """First time the unforced, damped oscillator from x = 0, v = V0 reaches the gap."""
    wd = np.sqrt(1 - XI**2)
    x = lambda t: V0 * np.exp(-XI * t) * np.sin(wd * t) / wd  # noqa: E731
    return brentq(lambda t: x(t) - GAP, 0.1, 1.5, xtol=1e-15)


def _instrumented(mp: pytest.MonkeyPatch) -> tuple[list[float], list[int]]:
    """Record the engine's located event times and count its partial steps (lists filled as
    it runs)."""
    times: list[float] = []
    switch = nm._switch

    def recorded(st, ma, a, evs, roots):
        rows = switch(st, ma, a, evs, roots)
        times.extend(st["t"][rows].tolist())
        return rows

    mp.setattr(nm, "_switch", recorded)
    steps = [0]
    state = ev._Partial.state

    def counted(self, s):
        steps[0] += 1
        return state(self, s)

    mp.setattr(ev._Partial, "state", counted)
    secant = nm._Model.kernel_secant

    def compiled(self, *args):  # the compiled secant's partial steps, one per pass
        out = secant(self, *args)
        steps[0] += out[1].shape[0]
        return out

    mp.setattr(nm._Model, "kernel_secant", compiled)
    return times, steps


def _run(effects: list, newton: bool, mp: pytest.MonkeyPatch) -> tuple[np.ndarray, object, int]:
    """Simulate one unforced row into contact; returns the located event times, the result
    and the partial steps taken."""
    batch = OscillatorBatch(
        np.array([30.0]), np.array([GAP]), np.array([0.0]), np.array([1.3]), np.array([XI])
    )
    params = [_rm(1) if isinstance(e, RestraintMass) else e.batch_params(1, None) for e in effects]
    if not newton:
        mp.setattr(nm._Model, "root_on_penetration", lambda self: np.zeros(self.n, dtype=bool))
    times, steps = _instrumented(mp)
    out = simulate_numerical(batch, effects, params, 0.0, V0, H, 0, H, 80, SUB)
    return np.array(times), out, steps[0]


@pytest.mark.parametrize(
    "effects", [[], [HertzContact()], [RestraintMass()]], ids=["base", "hertz", "restraint"]
)
def test_newton_locates_the_secants_contact_at_the_analytic_time(effects: list) -> None:
    with pytest.MonkeyPatch.context() as mp:
        t_new, new, n_new = _run(effects, True, mp)
    with pytest.MonkeyPatch.context() as mp:
        t_old, old, n_old = _run(effects, False, mp)
    assert t_new.size == t_old.size >= 2  # the entry and the release
    h_sub = H / SUB
    # the same roots of the same partial-step function: each within the tolerance
    assert np.all(np.abs(t_new - t_old) <= 2 * ev._ROOT_TOL * h_sub + 1e-15)
    if not effects or isinstance(effects[0], HertzContact):  # the free flight is the model's
        assert abs(t_new[0] - _free_flight_contact_time()) < 1e-8
    for key in ("x", "v", "accel", "contact_force"):
        np.testing.assert_allclose(getattr(new, key), getattr(old, key), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(new.impacts, old.impacts)
    assert n_new < n_old


def _rated(fun, rate_error: float):
    """``s -> (g, g' (1 + rate_error))``: a rate as inexact as the partial step's."""

    def both(s):
        g, d = fun(s)
        return g, d * (1 + rate_error)

    return both


@pytest.mark.parametrize("rate_error", [0.0, 1e-4, 0.3])
def test_newton_keeps_the_secants_contract(rate_error: float) -> None:
    """Far side of the root, within the tolerance: smooth roots from poor guesses, a root
    at the bracket's end, a start just after an event, a rate that is off, two rows."""
    rng = np.random.default_rng(5)
    cases = []
    for _ in range(30):
        r, c, hi = rng.uniform(0.05, 0.95), rng.uniform(-0.2, 3), rng.uniform(0.1, 2.0)

        def fun(s, r=r, c=c, hi=hi):
            u = s - r * hi
            return u * (1 + c * s * s), (1 + c * s * s) + u * 2 * c * s

        cases.append((fun, hi, r * hi, rng.uniform(0, hi)))
    cases.append((lambda s: (s - 0.3, np.ones_like(s)), 0.3, 0.3, 0.1))
    cases.append((lambda s: (np.where(s < 0.4, -1e-300, s - 0.4), np.ones_like(s)), 1.0, 0.4, 0.9))
    for fun, hi, root, guess in cases:
        f = _rated(fun, rate_error)
        g0, g1 = f(np.zeros(1))[0][0], f(np.array([hi]))[0][0]
        tol = 1e-13 * hi
        for n in (1, 2):
            got = ev._newton(f, np.full(n, hi), np.full(n, g0), np.full(n, g1),
                             np.full(n, tol), np.full(n, guess))  # fmt: skip
            assert np.all(got - root <= tol + 1e-16) and np.all(got >= root - 1e-16)
            assert np.all(f(got)[0] * np.sign(g0) <= 0)  # the far side


def test_hermite_guess_is_close_on_a_smooth_substep() -> None:
    """The cubic Hermite interpolant's root is far closer to the true one than the linear
    interpolant's (the secant's first point): here sin over a substep of 0.2, 4e-4 of the
    substep against 1.3e-2."""
    t0, hi = 0.4, 0.2
    root = np.pi / 6  # sin t = 0.5
    g0, g1 = np.sin(t0) - 0.5, np.sin(t0 + hi) - 0.5
    guess = ev._hermite_root(
        np.array([g0]), np.array([np.cos(t0)]), np.array([g1]), np.array([np.cos(t0 + hi)]),
        np.array([hi]),
    )  # fmt: skip
    assert abs(t0 + guess[0] - root) < 1e-3 * hi
    linear = t0 + g0 / (g0 - g1) * hi
    assert abs(t0 + guess[0] - root) < 0.05 * abs(linear - root)


def test_restraint_rate_is_the_zero_force_state_derivatives() -> None:
    """A restraint's own rate (its velocity state) is the rate the engine otherwise takes
    from the zero-force state derivative: the restraint's mass and a learned law's face."""
    from stiffnet.effects.learned_contact import LearnedContact

    rng = np.random.default_rng(2)
    face = LearnedContact(face_mass=0.5, face_stiffness=20.0, face2_mass=0.2,
                          face2_stiffness=40.0)  # fmt: skip
    for eff, p in ((RestraintMass(), _rm(5)), (face, face.batch_params(5, rng))):
        s = rng.normal(size=(5, eff.n_states))
        ds0 = eff.state_derivative(np.zeros(5), s, np.zeros(5), p)
        fd = eff.restraint_position(s + ds0, p) - eff.restraint_position(s, p)
        np.testing.assert_allclose(eff.restraint_rate(s, p), fd, rtol=1e-12, atol=1e-12)


MU = 0.15  # kinetic friction of the slip test: the unforced mass reverses, then sticks


def _slip_reversal_time() -> float:
    """First velocity reversal of the unforced, damped mass slipping forward from x = 0,
    v = V0 against a kinetic friction MU: x'' + 2 xi x' + x = -MU."""
    wd = np.sqrt(1 - XI**2)
    b = (V0 + XI * MU) / wd

    def v(t):
        c, s = np.cos(wd * t), np.sin(wd * t)
        return np.exp(-XI * t) * (-XI * (MU * c + b * s) + wd * (b * c - MU * s))

    return brentq(v, 0.1, 3.0, xtol=1e-15)


def _run_friction(newton: bool, mp: pytest.MonkeyPatch) -> tuple[np.ndarray, object, int]:
    """One unforced row slipping far from the restraint (no contact) until it sticks; returns
    the located event times, the result and the partial steps taken. ``newton=False``: the
    slip events by the secant (the effect gives no rate)."""
    batch = OscillatorBatch(
        np.array([30.0]), np.array([100.0]), np.array([0.0]), np.array([1.3]), np.array([XI])
    )
    eff = DryFriction(coefficient=MU, static_ratio=1.2)
    if not newton:
        mp.setattr(DryFriction, "event_rate", lambda self, *a: None)
    times, steps = _instrumented(mp)
    out = simulate_numerical(batch, [eff], [eff.batch_params(1, None)], 0.0, V0, H, 0, H, 400, SUB)
    return np.array(times), out, steps[0]


def test_newton_locates_the_secants_slip_reversal_at_the_analytic_time() -> None:
    """Dry friction's slip events (the function is the velocity, its rate the acceleration)
    by Newton steps: the secant's events within its tolerance, the first at the analytic
    reversal time, the same trajectory to round-off and the same sticking, in fewer partial
    steps."""
    with pytest.MonkeyPatch.context() as mp:
        t_new, new, n_new = _run_friction(True, mp)
    with pytest.MonkeyPatch.context() as mp:
        t_old, old, n_old = _run_friction(False, mp)
    assert t_new.size == t_old.size >= 3  # reversals, then sticking
    assert np.all(np.abs(t_new - t_old) <= 2 * ev._ROOT_TOL * H / SUB + 1e-15)
    assert abs(t_new[0] - _slip_reversal_time()) < 1e-8
    for key in ("x", "v", "accel"):
        np.testing.assert_allclose(getattr(new, key), getattr(old, key), rtol=0, atol=1e-12)
    assert np.all(np.abs(new.v[0, -20:]) < 1e-12)  # stuck at the end, as by the secant
    assert n_new < 0.7 * n_old


def test_dry_frictions_event_rate_is_its_event_functions_derivative() -> None:
    """The slip modes' rate is the event function's time derivative along a motion (a
    central difference of ``+/-v`` over a step of the constant-force motion); stuck: none."""
    eff = DryFriction(coefficient=0.2, static_ratio=1.2)
    p = eff.batch_params(3, None)
    mode = np.array([0.0, -1.0, STUCK])
    x, v, other = np.array([0.1, -0.2, 0.3]), np.array([0.5, -0.4, 0.0]), np.array([0.3, 0.1, 0.1])
    accel = other + eff.extra_force(np.zeros(3), x, v, other, mode, p)
    dt = 1e-6
    g = [eff.event_function(np.zeros(3), x, v + k * dt * accel, other, mode, p) for k in (-1, 1)]
    rate = eff.event_rate(np.zeros(3), x, v, accel, other, mode, p)
    np.testing.assert_allclose(rate[:2], ((g[1] - g[0]) / (2 * dt))[:2], rtol=1e-9)
    assert np.isnan(rate[2])


def test_dry_frictions_hooks_are_their_piecewise_definitions_bit_for_bit() -> None:
    """The force and the event function from the mode by a sign (the engine calls them at
    every right-hand side) equal the piecewise definitions exactly: ``-other`` / ``-mu_k`` /
    ``+mu_k`` and ``mu_s - |other|`` / ``v`` / ``-v``, signed zeros included."""
    eff = DryFriction()
    mode = np.repeat([0.0, -1.0, STUCK], 4)
    v = np.tile([0.7, -0.3, 0.0, -0.0], 3)
    other = np.tile([0.4, -2.0, 0.0, 1e-300], 3)
    for mu in (0.0, 1e-3, 0.18, 10.0):
        p = {"coefficient": np.full(12, mu), "static_ratio": np.full(12, 1.3)}
        force = eff.extra_force(np.zeros(12), v, v, other, mode, p)
        want = np.select([mode == STUCK, mode == -1.0], [-other, np.full(12, mu)], -mu)
        assert np.array_equal(force, want) and np.array_equal(np.signbit(force), np.signbit(want))
        g = eff.event_function(np.zeros(12), v, v, other, mode, p)
        want = np.select([mode == STUCK, mode == -1.0], [1.3 * mu - np.abs(other), -v], v)
        assert np.array_equal(g, want) and np.array_equal(np.signbit(g), np.signbit(want))
