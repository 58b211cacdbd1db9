"""The numerical engine's compiled RK4 step and right-hand side give numpy's numbers.

The kernel (:mod:`stiffnet.simulator.rk4_kernel`) reproduces ``_Model.rhs`` and ``_rk4``
for the library's own numerical effects (the same IEEE operations in the same order).
Expectation: every output of the engine with the kernel equals the numpy path's (switched
off by ``numerical.COMPILED_STEP``) to 1e-9 of its range (bitwise in practice), on each
numerical effect, their combination, contact damping, a gap sinusoid, a forcing harmonic,
sticking friction and the oversampled (dense-output) march; and an effect the kernel does
not know runs the numpy path.
"""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.effects.base import DynamicsEffect, ParamArrays, Sinusoids
from stiffnet.effects.contact_damping import ContactDamping
from stiffnet.effects.dry_friction import DryFriction
from stiffnet.effects.forcing_harmonics import ForcingHarmonics
from stiffnet.effects.hertz_contact import HertzContact
from stiffnet.effects.restraint_mass import RestraintMass
from stiffnet.simulator import numerical as nm
from stiffnet.simulator.numerical import simulate_numerical
from tests.test_simulator_numerical import W, _rm, paper_batch

K = 8
REL_TOL = 1e-9
KEYS = ("x", "v", "accel", "contact_force", "impacts")


class WobblingGap(DynamicsEffect):
    """A gap sinusoid: folded into the kernel's arrays."""

    name = "wobbling_gap"

    def gap_terms(self, p: ParamArrays, batch) -> Sinusoids:
        n = len(batch)
        return Sinusoids(np.full((n, 1), 0.15), np.full((n, 1), 0.37), np.full((n, 1), 0.4))


class PushyFriction(DryFriction):
    """A user's friction: its own force law, which the kernel does not know."""

    name = "pushy_friction"

    def extra_force(self, t, x, v, other, mode, p):
        return 1.5 * super().extra_force(t, x, v, other, mode, p)


def _params(effects: list[DynamicsEffect], n: int) -> list[ParamArrays]:
    rng = np.random.default_rng(0)
    out = []
    for e in effects:
        p = _rm(n) if isinstance(e, RestraintMass) else e.batch_params(n, rng)
        if isinstance(e, DryFriction):  # strong enough to stick at some reversals
            p = {**p, "coefficient": np.array([0.3, 1.2, 2.0])}
        out.append(p)
    return out


def _run(effects: list[DynamicsEffect], compiled: bool, dense: bool = False):
    batch = paper_batch()
    p = _params(effects, len(batch))
    h = 2 * np.pi / (W * np.array([800.0, 960.0, 880.0]))
    x0, v0 = np.zeros(3), np.array([0.0, 1.0, -0.5])
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(nm, "COMPILED_STEP", compiled)
        if dense:
            return simulate_numerical(
                batch, effects, p, x0, v0, 8 * h, 60, h, 4800, 2, oversampled=K
            )
        return simulate_numerical(batch, effects, p, x0, v0, 8 * h, 60, 8 * h, 600, 2)


CASES = {
    "hertz": [HertzContact()],
    "dry_friction": [DryFriction()],
    "restraint_mass": [RestraintMass()],
    "hertz_restraint_friction": [HertzContact(), RestraintMass(), DryFriction()],
    "friction_damped_contact": [ContactDamping(), DryFriction()],
    "hertz_wobbling_gap_harmonic": [HertzContact(), WobblingGap(), ForcingHarmonics()],
}


@pytest.mark.parametrize("dense", [False, True], ids=["plain", "oversampled"])
@pytest.mark.parametrize("name", list(CASES))
def test_the_kernels_trajectories_are_numpys(name: str, dense: bool) -> None:
    effects = CASES[name]
    batch = paper_batch()
    model = nm._Model(batch, effects, _params(effects, len(batch)))
    assert model.kernel is not None  # the case runs the kernel
    new = _run(effects, compiled=True, dense=dense)
    old = _run(effects, compiled=False, dense=dense)
    assert old.impacts.sum() >= 10  # events to locate in every case
    for key in KEYS:
        a, b = getattr(new, key).astype(float), getattr(old, key).astype(float)
        scale = max(float(np.ptp(b)), 1.0)
        assert np.max(np.abs(a - b)) <= REL_TOL * scale, key


def test_sticking_friction_is_exercised() -> None:
    """The friction cases stick (the kernel's ``-other`` branch runs): samples at rest."""
    out = _run([DryFriction()], compiled=True)
    assert (np.abs(out.v) < 1e-12).sum() >= 10


def test_the_kernels_right_hand_side_is_numpys_bit_for_bit() -> None:
    """``rhs(full=True)`` and one RK4 step, each row in and out of contact, every mode."""
    effects = [HertzContact(), RestraintMass(), DryFriction(), ContactDamping()]
    batch = paper_batch(np.array([5.0, 20.0, 80.0, 5.0, 20.0, 80.0]))
    p = _params(effects, 6)
    p[2] = {**p[2], "coefficient": np.full(6, 0.4)}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(nm, "COMPILED_STEP", False)
        slow = nm._Model(batch, effects, p)
    fast = nm._Model(batch, effects, p)
    rng = np.random.default_rng(5)
    t = rng.uniform(0, 300, 6)
    y = np.column_stack([rng.normal(2.8, 0.3, 6), rng.normal(0, 1, 6),
                         rng.normal(0, 0.01, 6), rng.normal(0, 0.1, 6)])  # fmt: skip
    contact = np.array([True, False, True, True, False, False])
    modes = np.zeros((len(effects), 6))
    modes[2] = [0.0, 1.0, -1.0, 1.0, 0.0, -1.0]
    dy_s, aux_s = slow.rhs(t, y, contact, modes, full=True)
    dy_f, aux_f = fast.rhs(t, y, contact, modes, full=True)
    np.testing.assert_array_equal(dy_f, dy_s)
    assert aux_f.keys() == aux_s.keys()
    for key in aux_s:
        np.testing.assert_array_equal(aux_f[key], aux_s[key])
    s = rng.uniform(0.001, 0.05, 6)
    np.testing.assert_array_equal(
        nm._rk4(fast, t, y, dy_s, s, contact, modes), nm._rk4(slow, t, y, dy_s, s, contact, modes)
    )


@pytest.mark.parametrize(
    "effects",
    [[PushyFriction()], [HertzContact(), HertzContact()]],
    ids=["user_subclass", "two_of_a_kind"],
)
def test_a_model_the_kernel_does_not_know_runs_numpys_path(effects) -> None:
    batch = paper_batch()
    params = _params(effects, len(batch))
    if len(effects) == 2:  # two elastic laws are refused by the engine itself
        assert nm.kernel_form(effects, Sinusoids.empty(3), Sinusoids.empty(3)) is None
        return
    assert nm._Model(batch, effects, params).kernel is None
