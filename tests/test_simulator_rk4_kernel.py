"""The numerical engine's compiled RK4 step and right-hand side give numpy's numbers.

The kernel (:mod:`stiffnet.simulator.rk4_kernel`) reproduces ``_Model.rhs`` and ``_rk4``
for the library's own numerical effects (the same IEEE operations in the same order).
Expectation: every output of the engine with the kernel equals the numpy path's (switched
off by ``numerical.COMPILED_STEP``) to 1e-9 of its range (bitwise in practice), on each
numerical effect, their combination, contact damping, a gap sinusoid, a forcing harmonic,
sticking friction and the oversampled (dense-output) march; the learned contact law's
terms each alone and together (second stage, preload, Hunt-Crossley and Kelvin-Voigt
dissipation, a face of one and two modes, terms on some rows only, a face that scales
with each row's beta alone, with every other term and on some rows only, on 1, 2 and 6 rows
of different betas), bit for bit; every
located event's time and state (the secant compiled with its evaluations,
``rk4_kernel.secant_rows``) bit for bit in every case and on rows located together, a
secant one unit in the last place off caught (and a scaled face's mass one unit off); and
an effect the kernel does not know runs the numpy path. A learned power law runs the
kernel, its right-hand side numpy's to round-off (numpy's SIMD ``pow`` is not the C
library's in the last bit) and its trajectories numpy's to 1e-6 of their range.
"""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.effects.base import DynamicsEffect, ParamArrays, Sinusoids
from stiffnet.effects.contact_damping import ContactDamping
from stiffnet.effects.dry_friction import DryFriction
from stiffnet.effects.forcing_harmonics import ForcingHarmonics
from stiffnet.effects.hertz_contact import HertzContact
from stiffnet.effects.learned_contact import LearnedContact
from stiffnet.effects.restraint_mass import RestraintMass
from stiffnet.simulator import events as ev
from stiffnet.simulator import numerical as nm
from stiffnet.simulator import rk4_kernel as rk
from stiffnet.simulator.numerical import simulate_numerical
from tests.test_simulator_numerical import E, W, _rm, paper_batch

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


#: A learned law whose terms differ by row (some rows without them), as a prior's draws or
#: a subset of rows make them: the hooks add a term to every row once one row has it. Its
#: rows' values are :data:`ROWWISE`'s (set by :func:`_params`).
ROWWISE_LAW = LearnedContact(face_mass=0.2)
#: Per-row values of :data:`ROWWISE_LAW` (three rows).
ROWWISE = {"knee_ratio": np.array([1.0, 3.0, 2.0]), "knee": np.array([0.1, 0.05, 0.2]),
           "preload": np.array([0.0, 0.0, 0.03]), "hunt_crossley": np.array([0.0, 0.5, 0.3]),
           "face_mass": np.array([0.2, 0.0, 0.3])}  # fmt: skip


#: A scaled face on some rows only (an absolute one, or none, on the others): the law's
#: hooks take every row's support and mass from :func:`~stiffnet.effects.learned_contact.
#: scaled_face`, which gives a row without the ratio its absolute face.
SCALED_ROWWISE_LAW = LearnedContact(face_mass=0.2, face_stiffness_ratio=1.5,
                                    face_mass_exponent=-0.3)  # fmt: skip
#: Per-row values of :data:`SCALED_ROWWISE_LAW` (three rows).
SCALED_ROWWISE = {"face_stiffness_ratio": np.array([1.25, 0.0, 3.0]),
                  "face_mass": np.array([0.2, 0.1, 0.0]),
                  "face_mass_exponent": np.array([-1 / 3, 0.5, 0.7]),
                  "face_beta_scale": np.array([0.8, 1.2, 1.0])}  # fmt: skip
ROWWISE_VALUES = {id(ROWWISE_LAW): ROWWISE, id(SCALED_ROWWISE_LAW): SCALED_ROWWISE}


def _params(effects: list[DynamicsEffect], n: int) -> list[ParamArrays]:
    rng = np.random.default_rng(0)
    out = []
    for e in effects:
        p = _rm(n) if isinstance(e, RestraintMass) else e.batch_params(n, rng)
        if isinstance(e, DryFriction):  # strong enough to stick at some reversals
            p = {**p, "coefficient": np.resize([0.3, 1.2, 2.0], n)}
        if id(e) in ROWWISE_VALUES:
            p = {**p, **{k: np.resize(v, n) for k, v in ROWWISE_VALUES[id(e)].items()}}
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


#: The learned law's terms, each alone, then together with the other effects.
LEARNED_FACE = {"face_mass": 0.3, "face_stiffness": 40.0, "face_damping": 0.05}
#: A face that is each row's own (a material beam's): support 1.25 beta, contact 5 beta,
#: mass 0.3 (beta / 30)^(-1/3).
SCALED_FACE = {"face_mass": 0.3, "face_stiffness_ratio": 1.25, "face_mass_exponent": -1 / 3,
               "face_damping": 0.05}  # fmt: skip


def _every_term(face: dict) -> list[DynamicsEffect]:
    """Every learned term at once with ``face`` as the first mode, beside the other effects
    the kernel covers."""
    terms = {"knee": 0.05, "knee_ratio": 2.5, "preload": 0.02, "hunt_crossley": 0.4,
             "damping_ratio": 0.05, "face2_mass": 0.1, "face2_stiffness": 400.0}  # fmt: skip
    law = LearnedContact(**terms, **face)
    return [law, WobblingGap(), ForcingHarmonics(), DryFriction()]


LEARNED_CASES = {
    "learned_two_stage": [LearnedContact(knee=0.05, knee_ratio=3.0)],
    "learned_preload": [LearnedContact(preload=0.02)],
    "learned_hunt_crossley": [LearnedContact(hunt_crossley=0.5)],
    "learned_kelvin_voigt": [LearnedContact(damping_ratio=0.1)],
    "learned_face": [LearnedContact(**LEARNED_FACE)],
    "learned_two_mode_face": [
        LearnedContact(**LEARNED_FACE, face2_mass=0.1, face2_stiffness=400.0)
    ],
    "learned_all_terms": _every_term(LEARNED_FACE),
    "learned_terms_on_some_rows": [ROWWISE_LAW, DryFriction()],
    "learned_scaled_face": [LearnedContact(**SCALED_FACE)],
    "learned_scaled_face_beta_scale": [LearnedContact(**SCALED_FACE, face_beta_scale=0.85)],
    "learned_scaled_face_all_terms": _every_term(SCALED_FACE),
    "learned_scaled_face_on_some_rows": [SCALED_ROWWISE_LAW, DryFriction()],
}
CASES = {
    "hertz": [HertzContact()],
    "dry_friction": [DryFriction()],
    "restraint_mass": [RestraintMass()],
    "hertz_restraint_friction": [HertzContact(), RestraintMass(), DryFriction()],
    "friction_damped_contact": [ContactDamping(), DryFriction()],
    "hertz_wobbling_gap_harmonic": [HertzContact(), WobblingGap(), ForcingHarmonics()],
    **LEARNED_CASES,
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
        if name in LEARNED_CASES:  # the learned law's kernel is held to the bit
            np.testing.assert_array_equal(a, b, err_msg=key)
        scale = max(float(np.ptp(b)), 1.0)
        assert np.max(np.abs(a - b)) <= REL_TOL * scale, key


def _kernel_and_numpy(batch, effects, params) -> tuple[nm._Model, nm._Model]:
    """The same model built with the compiled step and with numpy's path."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(nm, "COMPILED_STEP", False)
        slow = nm._Model(batch, effects, params)
    return nm._Model(batch, effects, params), slow


def _rhs_and_step(model: nm._Model, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """``rhs(full=True)``'s outputs and one RK4 step of ``model`` at random states near the
    learned laws' knee and face amplitudes, rows in and out of contact, every friction
    mode."""
    n = model.n
    t = rng.uniform(0, 300, n)
    y = np.column_stack([rng.normal(E + 0.05, 0.1, n), rng.normal(0, 1, n)]
                        + [rng.normal(0, 0.02, n) for _ in range(model.n_y - 2)])  # fmt: skip
    if any(type(e) is LearnedContact and e.scaled for e in model.effects):
        y[:, -1] = model.beta  # a scaled face's beta state: the row's (the engine keeps it)
    contact = np.arange(n) % 3 != 1
    modes = np.zeros((len(model.effects), n))
    if model.event_fx:
        modes[model.event_fx[0]] = np.resize([0.0, 1.0, -1.0, 1.0], n)
    dy, aux = model.rhs(t, y, contact, modes, full=True)
    s = rng.uniform(0.001, 0.05, n)
    step = nm._rk4(model, t, y, dy, s, contact, modes)
    return (dy, step, *(aux[k] for k in sorted(aux)))


@pytest.mark.parametrize("name", list(LEARNED_CASES))
def test_the_learned_laws_right_hand_side_is_numpys_bit_for_bit(name: str) -> None:
    """Each learned term's ``rhs(full=True)`` and RK4 step, on six rows and on a subset of
    them (the event locator's), equal numpy's to the bit."""
    effects = LEARNED_CASES[name]
    batch = paper_batch(np.array([5.0, 20.0, 80.0, 5.0, 20.0, 80.0]))
    p = _params(effects, 6)
    fast, slow = _kernel_and_numpy(batch, effects, p)
    assert fast.kernel is not None and fast.kernel.learned and slow.kernel is None
    for rows in (np.arange(6), np.array([0, 3]), np.array([4])):
        a, b = fast.subset(rows), slow.subset(rows)
        for x, y in zip(_rhs_and_step(a, np.random.default_rng(7)),
                        _rhs_and_step(b, np.random.default_rng(7)), strict=True):  # fmt: skip
            np.testing.assert_array_equal(x, y)


def test_a_perturbed_learned_kernel_is_caught() -> None:
    """The bitwise comparison sees one unit in the last place of one of the law's
    coefficients (the stage slope) in the kernel's pack."""
    effects = LEARNED_CASES["learned_all_terms"]
    batch = paper_batch(np.array([5.0, 20.0, 80.0, 5.0, 20.0, 80.0]))
    p = _params(effects, 6)
    fast, slow = _kernel_and_numpy(batch, effects, p)
    fast._pack[:, rk._SLOPE] = np.nextafter(fast._pack[:, rk._SLOPE], np.inf)
    got = _rhs_and_step(fast, np.random.default_rng(7))
    want = _rhs_and_step(slow, np.random.default_rng(7))
    assert any(not np.array_equal(x, y) for x, y in zip(got, want, strict=True))


#: The scaled face's cases (each row's contact, support and mass its own beta's).
SCALED_CASES = [n for n in LEARNED_CASES if "scaled" in n]
#: Rows of different betas (the scaled face's mass goes as numpy's ``pow`` of each).
OWN_BETAS = np.array([4.0, 9.5, 22.0, 30.0, 47.0, 83.0])


@pytest.mark.parametrize("name", SCALED_CASES)
def test_a_scaled_faces_right_hand_side_is_numpys_on_rows_of_their_own_betas(name: str) -> None:
    """A scaled face's ``rhs(full=True)`` and RK4 step on six rows of six betas, and on two
    rows and one row of them (the event locator's subsets), equal numpy's to the bit, the
    face's beta state held."""
    effects = LEARNED_CASES[name]
    batch = paper_batch(OWN_BETAS)
    fast, slow = _kernel_and_numpy(batch, effects, _params(effects, 6))
    assert fast.kernel is not None and fast.kernel.learned and slow.kernel is None
    assert fast.n_y % 2 == 1  # the face holds the row's beta
    for rows in (np.arange(6), np.array([1, 4]), np.array([5])):
        a, b = fast.subset(rows), slow.subset(rows)
        got = _rhs_and_step(a, np.random.default_rng(11))
        want = _rhs_and_step(b, np.random.default_rng(11))
        for x, y in zip(got, want, strict=True):
            np.testing.assert_array_equal(x, y)
        assert np.all(got[0][:, -1] == 0.0)  # d beta / dt


def test_a_scaled_faces_mass_one_ulp_off_is_caught() -> None:
    """The bitwise comparison sees one unit in the last place of a scaled face's mass (the
    row's ``face_mass (beta / beta_ref)**q``) in the kernel's pack."""
    effects = LEARNED_CASES["learned_scaled_face"]
    batch = paper_batch(OWN_BETAS)
    fast, slow = _kernel_and_numpy(batch, effects, _params(effects, 6))
    want = _rhs_and_step(slow, np.random.default_rng(11))
    assert all(np.array_equal(x, y) for x, y in
               zip(_rhs_and_step(fast, np.random.default_rng(11)), want, strict=True))  # fmt: skip
    mass = rk._FACE + 1
    fast._pack[:, mass] = np.nextafter(fast._pack[:, mass], np.inf)
    got = _rhs_and_step(fast, np.random.default_rng(11))
    assert any(not np.array_equal(x, y) for x, y in zip(got, want, strict=True))


def _run_rows(effects: list[DynamicsEffect], betas: np.ndarray, compiled: bool):
    """:func:`_run` on rows of the given betas, and every located event (:func:`_events`)."""
    n = betas.size
    batch = paper_batch(betas)
    p = _params(effects, n)
    h = 2 * np.pi / (W * np.resize([800.0, 960.0, 880.0], n))
    x0, v0 = np.zeros(n), np.resize([0.0, 1.0, -0.5], n)
    log: list[tuple[np.ndarray, ...]] = []
    switch = nm._switch

    def spy(st, ma, a, ev, roots):
        rows = switch(st, ma, a, ev, roots)
        log.append((st["t"][rows].copy(), st["y"][rows].copy(), st["contact"][rows].copy()))
        return rows

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(nm, "COMPILED_STEP", compiled)
        mp.setattr(nm, "_switch", spy)
        out = simulate_numerical(batch, effects, p, x0, v0, 8 * h, 60, 8 * h, 600, 2)
    return out, log


@pytest.mark.parametrize("rows", [1, 2, 6])
@pytest.mark.parametrize("name", SCALED_CASES)
def test_a_scaled_faces_engine_is_numpys_on_rows_of_their_own_betas(name: str, rows: int) -> None:
    """The whole engine with a scaled face on 1, 2 and 6 rows of different betas: every
    output and every located event's time and state, the compiled step against numpy's, to
    the bit."""
    effects, betas = LEARNED_CASES[name], OWN_BETAS[-rows:]
    new, new_events = _run_rows(effects, betas, compiled=True)
    old, old_events = _run_rows(effects, betas, compiled=False)
    assert old.impacts.sum() >= 5 * rows and len(old_events) >= 10
    for key in KEYS:
        np.testing.assert_array_equal(getattr(new, key), getattr(old, key), err_msg=key)
    assert _same_events(new_events, old_events)


def _events(effects: list[DynamicsEffect], compiled: bool, dense: bool = False, secant=None):
    """Every located event of :func:`_run`: the rows' time, state and region after each
    switch, in order; and the roots the compiled secant was asked for, by root function
    (``secant``: a replacement of ``_Model.kernel_secant``, default the engine's)."""
    log: list[tuple[np.ndarray, ...]] = []
    asked: dict = {}
    switch, kernel_secant = nm._switch, secant or nm._Model.kernel_secant

    def spy(st, ma, a, ev, roots):
        rows = switch(st, ma, a, ev, roots)
        log.append((st["t"][rows].copy(), st["y"][rows].copy(), st["contact"][rows].copy()))
        return rows

    def counted(self, start, root, bracket, iters, tiny):
        asked[root] = asked.get(root, 0) + 1
        return kernel_secant(self, start, root, bracket, iters, tiny)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(nm, "_switch", spy)
        mp.setattr(nm._Model, "kernel_secant", counted)
        _run(effects, compiled, dense)
    return log, asked


def _same_events(new: list, old: list) -> bool:
    """Whether two runs' events (:func:`_events`) are the same, to the bit."""
    return len(new) == len(old) and all(
        a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
        for got, want in zip(new, old, strict=True)
        for a, b in zip(got, want, strict=True)
    )


@pytest.mark.parametrize("dense", [False, True], ids=["plain", "oversampled"])
@pytest.mark.parametrize("name", list(CASES))
def test_every_located_event_is_numpys_bit_for_bit(name: str, dense: bool) -> None:
    """The event times and states, the compiled secant against numpy's path, to the bit."""
    new, asked = _events(CASES[name], compiled=True, dense=dense)
    old, none = _events(CASES[name], compiled=False, dense=dense)
    assert not none and len(old) >= 10
    assert _same_events(new, old)
    if name in LEARNED_CASES:  # their contact's root function is G or delta: the secant
        assert asked.get("Gr", 0) >= 10
    if any(type(e) is DryFriction for e in CASES[name]):
        assert asked.get(0, 0) + asked.get("Gr", 0) >= 1


def test_the_secant_roots_of_every_kind_are_compiled() -> None:
    """The cases exercise the compiled secant on the contact's root function, the grazing
    extremum of the penetration rate and the friction's event function."""
    asked: dict = {}
    for name in ("learned_all_terms", "learned_terms_on_some_rows", "friction_damped_contact"):
        for root, count in _events(CASES[name], compiled=True)[1].items():
            asked[root] = asked.get(root, 0) + count
    assert {"Gr", "dd", 0} <= set(asked)


def test_a_secant_one_ulp_off_is_caught() -> None:
    """The event comparison sees one unit in the last place of the gap (the root
    function's offset) in the compiled secant's evaluations alone (the steps between events
    untouched)."""

    def off(self, start, root, bracket, iters, tiny):
        pack = self._pack.copy()
        pack[:, rk._E0] = np.nextafter(pack[:, rk._E0], np.inf)
        return rk.secant_rows(self.kernel, pack, self.has_gap, self.has_cc, len(self.effects),
                             start, root, bracket, iters, tiny)  # fmt: skip

    effects = LEARNED_CASES["learned_two_stage"]
    new, _ = _events(effects, compiled=True, secant=off)
    old, _ = _events(effects, compiled=False)
    assert not _same_events(new, old)
    assert _same_events(_events(effects, compiled=True)[0], old)  # unperturbed: the same


def test_the_compiled_secant_is_numpys_on_rows_located_together() -> None:
    """Six rows leaving contact in one substep, their terms differing by row (the law's
    row-wide decisions): the compiled secant's roots, every state it computed and the
    states the switch reuses equal numpy's vectorised secant's, to the bit."""
    effects = [ROWWISE_LAW, DryFriction()]
    batch = paper_batch(np.array([5.0, 20.0, 80.0, 5.0, 20.0, 80.0]))
    fast, slow = _kernel_and_numpy(batch, effects, _params(effects, 6))
    rng = np.random.default_rng(3)
    y = np.zeros((6, fast.n_y))
    y[:, 0] = E + rng.uniform(1e-4, 2e-3, 6)  # just in contact, leaving it
    y[:, 1] = -rng.uniform(0.3, 1.0, 6)
    t, contact = rng.uniform(0, 300, 6), np.ones(6, dtype=bool)
    modes = np.zeros((2, 6))
    modes[1] = [1.0, -1.0, 1.0, -1.0, 1.0, -1.0]  # slipping
    f, aux0 = slow.rhs(t, y, contact, modes, full=True)
    st = {"t": t, "y": y, "f": f, "contact": contact, "modes": modes}
    rows, hi = np.arange(6), np.full(6, 0.02)
    ghi = ev._Partial(st, slow, rows, rows).aux(hi)["Gr"]
    assert np.all(aux0["Gr"] > 0) and np.all(ghi < 0)  # a crossing on every row
    got = []
    for model in (fast, slow):
        part = ev._Partial(st, model, rows, rows)
        root = part.secant("Gr", hi, aux0["Gr"], ghi, np.full(6, 1e-13 * 0.02))
        got.append((root, part.seen, part.state_at(root)))
    (root_f, seen_f, (ok_f, y_f)), (root_s, seen_s, (ok_s, y_s)) = got
    assert root_f.tobytes() == root_s.tobytes() and np.all(root_f < 0.02)
    assert len(seen_f) == len(seen_s) >= 3
    for (s_f, ys_f), (s_s, ys_s) in zip(seen_f, seen_s, strict=True):
        assert s_f.tobytes() == s_s.tobytes() and ys_f.tobytes() == ys_s.tobytes()
    assert ok_f.all() and ok_s.all() and y_f.tobytes() == y_s.tobytes()


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
    fast, slow = _kernel_and_numpy(batch, effects, p)
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


def _numpys_suspects(model, aux0, contact, aux1, hs) -> np.ndarray:
    """``_Stepper._suspects`` of a substep from switching data ``aux0`` to ``aux1``."""
    st = object.__new__(nm._Stepper)
    st.m, st.aux, st.contact = model, aux0, contact
    return st._suspects(aux1, hs)


@pytest.mark.parametrize(
    "name", ["learned_all_terms", "learned_scaled_face", "hertz_restraint_friction",
             "friction_damped_contact"],
)  # fmt: skip
def test_a_compiled_substep_is_numpys_step_right_hand_side_and_suspects(name: str) -> None:
    """The march's substep in one compiled call (``rk4_kernel.substep``): the state, its
    right-hand side and switching data at the substep's end and the rows to resolve equal
    numpy's three calls' (``_rk4``, ``rhs(full=True)``, ``_Stepper._suspects``) to the bit,
    on 60 rows near the restraint, in and out of contact, some of them to resolve."""
    effects = CASES[name]
    n = 60
    batch = paper_batch(np.resize(OWN_BETAS, n))
    fast, slow = _kernel_and_numpy(batch, effects, _params(effects, n))
    assert fast.kernel is not None and slow.kernel is None
    rng = np.random.default_rng(3)
    t = rng.uniform(0, 300, n)
    y = np.column_stack([rng.normal(E, 0.05, n), rng.normal(0, 0.5, n)]
                        + [rng.normal(0, 0.02, n) for _ in range(slow.n_y - 2)])  # fmt: skip
    if any(type(e) is LearnedContact and e.scaled for e in effects):
        y[:, -1] = slow.beta  # a scaled face's beta state: the row's
    contact = rng.random(n) < 0.5
    modes = np.zeros((len(effects), n))
    if slow.event_fx:
        modes[slow.event_fx[0]] = np.resize([0.0, 1.0, -1.0, 1.0], n)
    f0, aux0 = slow.rhs(t, y, contact, modes, full=True)
    hs = rng.uniform(0.005, 0.1, n)
    t1 = t + hs
    y1 = nm._rk4(slow, t, y, f0, hs, contact, modes)
    f1, aux1 = slow.rhs(t1, y1, contact, modes, full=True)
    want = _numpys_suspects(slow, aux0, contact, aux1, hs)
    got_y, got_f, got_aux, got = fast.kernel_substep(t, y, f0, hs, t1, contact, modes, aux0)
    np.testing.assert_array_equal(got_y, y1)
    np.testing.assert_array_equal(got_f, f1)
    assert got_aux.keys() == aux1.keys()
    for key in aux1:
        np.testing.assert_array_equal(got_aux[key], aux1[key], err_msg=key)
    np.testing.assert_array_equal(got, want)
    assert 0 < want.size < n  # rows to resolve and rows that are not


def test_the_march_takes_each_substep_in_one_compiled_call(monkeypatch) -> None:
    """A model the kernel steps marches through ``rk4_kernel.substep`` (the trajectories'
    test above then holds it to numpy's path); numpy's path never calls it."""
    calls = []
    real = nm.substep

    def spy(*args):
        calls.append(1)
        return real(*args)

    monkeypatch.setattr(nm, "substep", spy)
    _run(LEARNED_CASES["learned_scaled_face"], compiled=True)
    assert len(calls) >= 600  # the record's steps at least
    calls.clear()
    _run(LEARNED_CASES["learned_scaled_face"], compiled=False)
    assert not calls


class StiffeningLaw(LearnedContact):
    """A user's subclass of the learned law: it may override a hook, so numpy's path."""

    name = "stiffening_law"


@pytest.mark.parametrize(
    "effects",
    [
        [PushyFriction()],
        [StiffeningLaw(knee_ratio=2.0)],
        [HertzContact(), HertzContact()],
        [HertzContact(), LearnedContact()],
    ],
    ids=["user_subclass", "learned_subclass", "two_of_a_kind", "two_elastic_laws"],
)  # fmt: skip
def test_a_model_the_kernel_does_not_know_runs_numpys_path(effects) -> None:
    batch = paper_batch()
    params = _params(effects, len(batch))
    if len(effects) == 2:  # two elastic laws are refused by the engine itself
        assert nm.kernel_form(effects, params, Sinusoids.empty(3), Sinusoids.empty(3)) is None
        return
    assert nm._Model(batch, effects, params).kernel is None


#: A power law on every row, then on some rows only (exponent 1 on the first: the linear
#: law's operations there).
POWER_ROWWISE_LAW = LearnedContact(exponent=1.3, preload=0.01, hunt_crossley=0.3, knee=0.05)
ROWWISE_VALUES[id(POWER_ROWWISE_LAW)] = {"exponent": np.array([1.0, 1.3, 1.6])}
POWER_CASES = {
    "power_law": [LearnedContact(exponent=1.3)],
    "power_law_preload": [LearnedContact(exponent=1.6, preload=0.02)],
    "power_law_all_terms": [
        LearnedContact(exponent=1.3, preload=0.02, hunt_crossley=0.4, knee=0.05, knee_ratio=2.0,
                       damping_ratio=0.05, **LEARNED_FACE), WobblingGap(), ForcingHarmonics()
    ],
    "power_law_on_some_rows": [POWER_ROWWISE_LAW],
}  # fmt: skip


def _scaled_close(got: np.ndarray, want: np.ndarray, rtol: float) -> None:
    """``got`` equals ``want`` within ``rtol`` of ``want``'s range."""
    got, want = np.asarray(got, float), np.asarray(want, float)
    span = float(np.ptp(want)) if want.size else 0.0
    np.testing.assert_allclose(got, want, rtol=0, atol=rtol * max(span, 1e-300))


@pytest.mark.parametrize("name", list(POWER_CASES))
def test_a_learned_power_laws_right_hand_side_is_numpys_to_round_off(name: str) -> None:
    """A power law runs the kernel; its ``rhs(full=True)`` and RK4 step equal numpy's to
    1e-12 of their range (the C library's ``pow`` against numpy's SIMD one)."""
    effects = POWER_CASES[name]
    batch = paper_batch(np.array([5.0, 20.0, 80.0, 5.0, 20.0, 80.0]))
    p = _params(effects, 6)
    fast, slow = _kernel_and_numpy(batch, effects, p)
    assert fast.kernel is not None and fast.kernel.learned and slow.kernel is None
    for x, y in zip(_rhs_and_step(fast, np.random.default_rng(7)),
                    _rhs_and_step(slow, np.random.default_rng(7)), strict=True):  # fmt: skip
        _scaled_close(x, y, 1e-12)


def test_a_power_law_with_another_exponent_in_the_kernel_is_caught() -> None:
    """The comparison sees the kernel's exponent moved by 1e-6."""
    effects = POWER_CASES["power_law_all_terms"]
    batch = paper_batch(np.array([5.0, 20.0, 80.0, 5.0, 20.0, 80.0]))
    fast, slow = _kernel_and_numpy(batch, effects, _params(effects, 6))
    fast._pack[:, rk._EXPO] += 1e-6
    got = _rhs_and_step(fast, np.random.default_rng(7))
    want = _rhs_and_step(slow, np.random.default_rng(7))
    with pytest.raises(AssertionError):
        for x, y in zip(got, want, strict=True):
            _scaled_close(x, y, 1e-12)


@pytest.mark.parametrize("name", list(POWER_CASES))
def test_a_learned_power_laws_trajectories_are_numpys(name: str) -> None:
    """The engine's records with a power law through the kernel equal numpy's path's to
    1e-6 of their range, the same impacts."""
    new = _run(POWER_CASES[name], compiled=True)
    old = _run(POWER_CASES[name], compiled=False)
    assert old.impacts.sum() >= 5
    np.testing.assert_array_equal(new.impacts, old.impacts)
    for key in ("x", "v", "accel", "contact_force"):
        _scaled_close(getattr(new, key), getattr(old, key), 1e-6)
