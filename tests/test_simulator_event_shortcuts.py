"""The numerical engine's event location without its redundant work, bit for bit.

Locating an event evaluates a switching function after RK4 partial steps, 4-6 times per
event. Two shortcuts cut the right-hand sides this needs: the penetration and its rate
(the contact's root function without contact damping, and the grazing extremum's) are read
off the partial step's state, without the forces; and the step to the located event reuses
the partial step the root finder already computed at that length. Both give the very same
numbers: expectation, outputs equal bit for bit with the shortcuts switched off, for the
plain and the oversampled (dense-output) march, with a contact law, an event effect, a
wobbling gap and a moving restraint (where the shortcut does not apply).
"""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.effects.base import DynamicsEffect, ParamArrays, Sinusoids
from stiffnet.effects.dry_friction import DryFriction
from stiffnet.effects.hertz_contact import HertzContact
from stiffnet.effects.restraint_mass import RestraintMass
from stiffnet.simulator import numerical as nm
from stiffnet.simulator.numerical import simulate_numerical
from tests.test_simulator_numerical import W, _rm, paper_batch

K = 8


class WobblingGap(DynamicsEffect):
    """A gap sinusoid alone: the penetration's root function is still read off the state."""

    name = "wobbling_gap"

    def gap_terms(self, p: ParamArrays, batch) -> Sinusoids:
        n = len(batch)
        return Sinusoids(np.full((n, 1), 0.15), np.full((n, 1), 0.37), np.full((n, 1), 0.4))


def _params(effects: list[DynamicsEffect], n: int) -> list[ParamArrays]:
    rng = np.random.default_rng(0)
    return [_rm(n) if isinstance(e, RestraintMass) else e.batch_params(n, rng) for e in effects]


def _run(effects: list[DynamicsEffect], dense: bool):
    batch = paper_batch()
    p = _params(effects, len(batch))
    h = 2 * np.pi / (W * np.array([800.0, 960.0, 880.0]))
    x0, v0 = np.zeros(3), np.array([0.0, 1.0, -0.5])
    if dense:
        return simulate_numerical(batch, effects, p, x0, v0, 8 * h, 60, h, 4800, 2, oversampled=K)
    return simulate_numerical(batch, effects, p, x0, v0, 8 * h, 60, 8 * h, 600, 2)


def _switched_off(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(nm._Model, "reads_state", lambda self, key: False)

    def nothing_known(self, s):
        return np.zeros(s.size, dtype=bool), np.empty_like(self.y)

    monkeypatch.setattr(nm._Partial, "state_at", nothing_known)


def _count_rhs(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    # counted on numpy's path: the compiled RK4 step (rk4_kernel) calls no ``rhs``
    monkeypatch.setattr(nm, "COMPILED_STEP", False)
    calls = [0]
    rhs = nm._Model.rhs

    def counted(self, *args, **kwargs):
        calls[0] += 1
        return rhs(self, *args, **kwargs)

    monkeypatch.setattr(nm._Model, "rhs", counted)
    return calls


@pytest.mark.parametrize("dense", [False, True], ids=["plain", "oversampled"])
@pytest.mark.parametrize(
    "effects",
    [
        [HertzContact()],
        [DryFriction()],
        [WobblingGap()],
        [RestraintMass()],  # only the reused step: its restraint needs the hooks
    ],
    ids=["hertz", "dry_friction", "wobbling_gap", "restraint_mass"],
)
def test_shortcuts_give_the_same_bits_with_fewer_right_hand_sides(
    effects: list[DynamicsEffect], dense: bool
) -> None:
    with pytest.MonkeyPatch.context() as mp:
        calls = _count_rhs(mp)
        fast = _run(effects, dense)
        n_fast = calls[0]
    with pytest.MonkeyPatch.context() as mp:
        _switched_off(mp)
        calls = _count_rhs(mp)
        slow = _run(effects, dense)
        n_slow = calls[0]
    assert slow.impacts.sum() >= 10  # events to locate in every case
    for key in ("x", "v", "accel", "contact_force", "impacts"):
        np.testing.assert_array_equal(getattr(fast, key), getattr(slow, key))
    # at least one right-hand side saved per located event
    assert n_slow - n_fast >= slow.impacts.sum()


@pytest.mark.parametrize(
    "effects, reads",
    [([], True), ([HertzContact()], True), ([WobblingGap()], True), ([RestraintMass()], False)],
    ids=["base", "hertz", "wobbling_gap", "restraint_mass"],
)
def test_state_value_is_the_right_hand_sides_aux(effects, reads: bool) -> None:
    """Where the model reads the root function off the state, the numbers are ``rhs``'s."""
    batch = paper_batch()
    model = nm._Model(batch, effects, _params(effects, len(batch)))
    rng = np.random.default_rng(3)
    t = rng.uniform(0, 300, 3)
    y = model.initial_state(rng.normal(2.8, 0.3, 3), rng.normal(0, 1, 3))
    y[:, :2] = np.column_stack([rng.normal(2.8, 0.3, 3), rng.normal(0, 1, 3)])
    contact = np.array([True, False, True])
    modes = np.zeros((len(effects), 3))
    aux = model.rhs(t, y, contact, modes, full=True)[1]
    for key in ("Gr", "dd"):
        assert model.reads_state(key) is reads
        if reads:
            assert np.array_equal(model.state_value(t, y, key), aux[key])


def test_contact_damping_keeps_the_full_root_function() -> None:
    """With contact damping the root function is the force's, not the penetration."""
    from tests.test_simulator_numerical import LinearHooks

    batch = paper_batch()
    model = nm._Model(batch, [LinearHooks()], [{}])
    assert not model.reads_state("Gr") and model.reads_state("dd")


def test_one_row_root_finder_is_the_batch_one_bit_for_bit() -> None:
    """The Python-float Illinois for one row returns the very root the numpy one finds for
    that row inside a batch, and the root to the tolerance: smooth roots, a root on the
    bracket's end, a step (bisection only), a start on the boundary (just after an event)."""
    rng = np.random.default_rng(11)
    cases = []
    for _ in range(40):
        r, c, hi = rng.uniform(0.05, 0.95), rng.uniform(-0.2, 3), rng.uniform(0.1, 2.0)
        cases.append((lambda s, r=r, c=c, hi=hi: (s - r * hi) * (1 + c * s * s), hi, r * hi))
    cases.append((lambda s: s - 0.3, 0.3, 0.3))
    cases.append((lambda s: np.where(s < 0.6, -1.0, 1.0), 1.0, 0.6))
    cases.append((lambda s: np.where(s < 0.4, -1e-300, s - 0.4), 1.0, 0.4))
    for fun, hi, root in cases:
        h = np.array([hi, hi])
        g0, g1 = fun(np.zeros(1))[0], fun(np.array([hi]))[0]
        glo, ghi = np.full(2, g0), np.full(2, g1)
        tol = np.full(2, 1e-13 * hi)
        both = nm._illinois(fun, h, glo, ghi, tol)
        one = nm._illinois(fun, h[:1], glo[:1], ghi[:1], tol[:1])
        assert one.shape == (1,)
        assert both[0] == both[1] == one[0]
        assert abs(one[0] - root) <= 2e-13 * hi
