"""The numerical engine's RK4 step compiled with numba, for the library's own effects.

Event location marches one or two rows at a time through RK4 partial steps (two or three
per event, each of three right-hand sides), where numpy's cost per call on one-element
arrays, not the arithmetic, is the engine's cost. Where every dynamics effect of a model
is one this module knows (:data:`KNOWN_EFFECTS`: the Hertz contact law, dry friction, the
restraint's own mass, the learned contact law; the effects that only add forcing or gap
sinusoids or contact damping are folded into the model's arrays), :func:`rk4_step` takes
the step in one compiled loop over the rows: the same IEEE operations in the same order as
:meth:`~stiffnet.simulator.numerical._Model.rhs` (``full=False``) and
:func:`~stiffnet.simulator.rk4._rk4`, so bitwise the same states. Any other effect (a
user's), or more than :data:`MAX_TERMS` sinusoids, keeps the numpy path.

The learned law (:class:`~stiffnet.effects.learned_contact.LearnedContact`) runs here:
its second stage, preload, Hunt-Crossley and Kelvin-Voigt dissipation and its face's one
or two modes, bit for bit on rows whose leading term is linear (``exponent`` 1). A row with
a power-law leading term runs here too, but to the last bit only mostly: numpy's ``**`` on
float arrays is its own SIMD ``pow`` (SVML on AVX-512 machines), which differs from the C
library's, numba's, in the last bit on about one value in twenty. The engine's numpy path
cost 10-13x the kernel's (a law of exponent 1.3, three rows, 15 impacts: 0.36 s against
0.027 s for the linear law compiled), and a power law's every simulation paid it (a
diagnosis's chain refit with a power law: 4.2 s an evaluation against 0.8 s for a
linear two-stage law); a trajectory of the kernel's is as exact as numpy's, its round-off
only another. Its coefficients come from the law's own
:func:`~stiffnet.effects.learned_contact.law_coefficients`. A face that scales with beta
(``face_stiffness_ratio`` > 0) runs here too: its contact ``beta r / (r - 1)``, support
``r beta`` and mass ``face_mass (beta / beta_ref)**q`` are packed per row by the law's own
:func:`~stiffnet.effects.learned_contact.scaled_face` on the batch's beta, numpy's ``pow``
included (element by element the same whatever the array's length, measured), which the
hooks compute again from the face's beta state at every call, a state RK4 keeps to the bit.

The event locator's Illinois secant runs here too (:func:`secant_rows`): its RK4 partial
steps and root-function evaluations in one compiled call, row by row in the vectorised
loop's operations and order, where each evaluation from Python cost two wrapped kernel calls
and a search of the states already computed. The brackets, the Newton locator and the
switch stay in Python (:mod:`.events`). So does the march's substep (:func:`substep`): the
RK4 step, the right-hand side at its end and the rows to resolve in one call on the whole
batch, where three calls from Python and numpy's test of the rows cost as much as the
arithmetic on tens of rows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np

from stiffnet.effects.base import DynamicsEffect, ParamArrays, Sinusoids
from stiffnet.effects.dry_friction import STUCK, DryFriction
from stiffnet.effects.hertz_contact import HertzContact
from stiffnet.effects.learned_contact import LearnedContact, law_coefficients
from stiffnet.effects.restraint_mass import RestraintMass

if TYPE_CHECKING:
    from stiffnet.simulator.batch import OscillatorBatch

#: The effects whose numerical hooks the kernel reproduces (their exact classes: a
#: subclass may override a hook).
KNOWN_EFFECTS = (HertzContact, DryFriction, RestraintMass, LearnedContact)
#: The hooks an effect may override and still run here when it is one of the known.
_HOOKS = (
    "elastic_contact",
    "contact_dissipation",
    "extra_force",
    "event_function",
    "restraint_position",
    "state_derivative",
)
#: Sinusoids per forcing or gap sum the kernel takes: it adds them left to right, as
#: numpy's ``sum(axis=1)`` does on so few (its pairwise summation starts at 8 terms).
MAX_TERMS = 4

# the per-row pack's columns
_E0, _XI2, _BETA, _CC, _KH, _MUK, _MUS, _MU, _KAPPA, _RDAMP = range(10)
# the learned law's: knee, stage slope, preload, Hunt-Crossley gain, the contact's own
# stiffness (beta, or a scaled face's beta r / (r - 1)), whether the first mode's rate moves
# the face (its declared mass > 0)
_KNEE, _SLOPE, _PRE, _HCG, _KC, _FACE_ON = range(10, 16)
# the learned law's leading term: its exponent p and reference penetration d_r
_EXPO, _DR = 16, 17
_FACE = 18  # the learned face's modes: has, m, stiffness, c per mode, two modes
_MODE_KEYS = ("has", "m", "stiffness", "c")
_FORCING = _FACE + 2 * len(_MODE_KEYS)  # amp, freq, phase per term, MAX_TERMS terms
_GAP = _FORCING + 3 * MAX_TERMS
_N_COLS = _GAP + 3 * MAX_TERMS


@dataclass(frozen=True)
class KernelForm:
    """Which of the known effects a model holds (the rows' values are in the pack).

    ``hertz``: the elastic law is the Hertz one (else ``beta delta``); ``friction``: the
    index of the dry-friction effect in the model's effects (its mode row), -1 if none;
    ``restraint``: the restraint's mass states sit at columns 2-3 of the state;
    ``learned``: the contact law is the learned one (linear leading term), whose face's
    ``n_face`` modes sit at columns 2-3 and 4-5, and a face that scales with beta holds the
    row's beta in the next column (its derivative 0; the rows' support, mass and contact
    are packed from the batch's beta, the value that state keeps: RK4 adds zeros to it).
    """

    hertz: bool
    friction: int
    restraint: bool
    n_forcing: int
    n_gap: int
    learned: bool = False
    n_face: int = 0


def kernel_form(
    effects: list[DynamicsEffect],
    params: list[ParamArrays],
    forcing: Sinusoids,
    gap: Sinusoids,
) -> KernelForm | None:
    """The model's :class:`KernelForm`, or None where the kernel cannot reproduce its
    right-hand side (an unknown effect overriding a numerical hook, two of a kind, two
    elastic laws, a learned law with a power-law leading term, too many sinusoids)."""
    seen: set[type] = set()
    friction = -1
    n_face = 0
    for k, eff in enumerate(effects):
        hooks = [h for h in _HOOKS if getattr(type(eff), h) is not getattr(DynamicsEffect, h)]
        if not hooks and not eff.n_states:
            continue  # forcing, gap or contact damping only: folded into the arrays
        if type(eff) not in KNOWN_EFFECTS or type(eff) in seen:
            return None
        seen.add(type(eff))
        if type(eff) is DryFriction:
            friction = k
        if type(eff) is LearnedContact:
            n_face = eff.n_states // 2  # a scaled face's beta state is the odd one
    if forcing.amp.shape[1] > MAX_TERMS or gap.amp.shape[1] > MAX_TERMS:
        return None
    if HertzContact in seen and LearnedContact in seen:
        return None
    if RestraintMass in seen and any(e.n_states for e in effects if type(e) is not RestraintMass):
        return None
    return KernelForm(
        hertz=HertzContact in seen,
        friction=friction,
        restraint=RestraintMass in seen,
        n_forcing=forcing.amp.shape[1],
        n_gap=gap.amp.shape[1],
        learned=LearnedContact in seen,
        n_face=n_face,
    )


def kernel_pack(
    form: KernelForm,
    effects: list[DynamicsEffect],
    params: list[ParamArrays],
    batch: OscillatorBatch,
    forcing: Sinusoids,
    gap: Sinusoids,
    cc: np.ndarray,
) -> np.ndarray:
    """The rows' values the kernel reads, (B, columns): each derived from the parameters
    by the same numpy expression as the hooks' (bitwise the same coefficients)."""
    n = len(batch)
    pack = np.zeros((n, _N_COLS))
    pack[:, _E0], pack[:, _XI2], pack[:, _BETA] = batch.gap, 2.0 * batch.damping, batch.beta
    pack[:, _CC] = cc
    for eff, p in zip(effects, params, strict=True):
        if type(eff) is HertzContact:
            pack[:, _KH] = batch.beta / np.sqrt(p["reference_penetration"])
        elif type(eff) is DryFriction:
            pack[:, _MUK] = p["coefficient"]
            pack[:, _MUS] = p["static_ratio"] * p["coefficient"]
        elif type(eff) is RestraintMass:
            mu, kappa = p["mass_ratio"], p["stiffness_ratio"]
            pack[:, _MU], pack[:, _KAPPA] = mu, kappa
            pack[:, _RDAMP] = 2.0 * p["damping_ratio"] * np.sqrt(kappa * mu)
        elif type(eff) is LearnedContact:
            # a scaled face's mass (beta / beta_ref)**q by numpy's own pow, once per row: the
            # hooks compute it from the beta state at every call, the same value each time
            law = law_coefficients(p, batch.beta, scaled=eff.scaled)
            pack[:, _KNEE], pack[:, _SLOPE] = law["knee"], law["stage_slope"]
            pack[:, _PRE], pack[:, _HCG] = law["preload"], law["hunt_crossley_gain"]
            pack[:, _KC], pack[:, _FACE_ON] = law["contact"], law["face_on"]
            pack[:, _EXPO], pack[:, _DR] = p["exponent"], p["reference_penetration"]
            for j, mode in enumerate(("face", "face2")):
                for c, key in enumerate(_MODE_KEYS):
                    pack[:, _FACE + len(_MODE_KEYS) * j + c] = law[f"{mode}_{key}"]
    for col, sines, n_terms in ((_FORCING, forcing, form.n_forcing), (_GAP, gap, form.n_gap)):
        for j in range(n_terms):
            pack[:, col + 3 * j] = sines.amp[:, j]
            pack[:, col + 3 * j + 1] = sines.freq[:, j]
            pack[:, col + 3 * j + 2] = sines.phase[:, j]
    return pack


def _jit(func):
    return numba.njit(cache=True, error_model="numpy")(func)


def _jit_inline(func):
    """A row's helper, inlined by numba into each compiled loop that calls it: a call with
    twenty arguments per right-hand side cost more than the right-hand side's arithmetic
    (a substep of 64 rows of the scaled face, 32 -> 14 us); the same IEEE operations in the
    same order, so the same bits. The loops compile slower once (a cold cache)."""
    return numba.njit(cache=True, error_model="numpy", inline="always")(func)


@_jit_inline
def _sines(p, col, n_terms, t, rate):
    """The sum of a row's sinusoids at ``t`` (``rate``: its time derivative), in
    :class:`~stiffnet.simulator.numerical._Sines`' operations and order."""
    out = 0.0
    for j in range(n_terms):
        amp, freq, phase = p[col + 3 * j], p[col + 3 * j + 1], p[col + 3 * j + 2]
        if rate:
            term = amp * freq * math.cos(freq * t + phase)
        else:
            term = amp * math.sin(freq * t + phase)
        out = term if j == 0 else out + term
    return out


@_jit_inline
def _clip(x):
    """``np.maximum(x, 0.0)`` (NaN propagated)."""
    return x if (x >= 0.0 or x != x) else 0.0


@_jit
def _learned_flags(pack):
    """Whether any row has a preload, and any the Hunt-Crossley term: the learned law's
    hooks add those terms to every row of a model where one row has them."""
    has_pre, has_diss = False, False
    for i in range(pack.shape[0]):
        has_pre = has_pre or pack[i, _PRE] != 0.0
        has_diss = has_diss or pack[i, _HCG] != 0.0
    return has_pre, has_diss


@_jit_inline
def _rhs(p, t, y, contact, mode, f_t, has_gap, has_cc, hertz, friction, restraint,
         n_gap, learned, n_face, has_pre, has_diss, dy):  # fmt: skip
    """dy/dt of one row into ``dy`` (``_Model.rhs``); ``f_t`` the forcing at ``t``.
    Returns what the switching data are made of: ``delta, dd, fpot, base, total`` and the
    friction force ``fk`` (0 without friction)."""
    x, v = y[0], y[1]
    if has_gap:
        e = p[_E0] + _sines(p, _GAP, n_gap, t, False)
        de = _sines(p, _GAP, n_gap, t, True)
    else:
        e, de = p[_E0], 0.0
    yr, dyr = 0.0, 0.0
    if restraint:
        yr, dyr = 0.0 + y[2], 0.0 + y[3]
    elif n_face:  # LearnedContact.restraint_position and restraint_rate
        r = y[2] if n_face == 1 else y[2] + y[4]
        rate = y[3] if p[_FACE_ON] != 0.0 else 0.0
        if n_face == 2:
            rate = rate + (y[5] if p[_FACE + len(_MODE_KEYS)] != 0.0 else 0.0)
        yr, dyr = 0.0 + r, 0.0 + rate
    delta = x - e - yr
    dd = v - de - dyr
    if hertz:
        d = delta if delta > 0.0 else 0.0
        elastic = p[_KH] * d * math.sqrt(d)
    elif learned:  # k_c (d + (r - 1) max(d - knee, 0) [+ preload]), d = max(delta, 0)
        d = _clip(delta)
        if p[_EXPO] == 1.0:
            shape = d + p[_SLOPE] * _clip(d - p[_KNEE])
            if has_pre:
                shape = shape + (p[_PRE] if d > 0.0 else 0.0)
        else:  # learned_contact.elastic_shape: d_r ((d + d_0) / d_r)**p + (r - 1) max(d - k, 0)
            lead = p[_DR] * (d / p[_DR]) ** p[_EXPO]
            if has_pre:
                lead = p[_DR] * (_clip(d + p[_PRE]) / p[_DR]) ** p[_EXPO] if d > 0.0 else 0.0
            shape = lead + p[_SLOPE] * _clip(d - p[_KNEE])
        elastic = p[_KC] * shape
    else:
        elastic = p[_BETA] * delta
    fpot = elastic + p[_CC] * dd if has_cc else elastic
    if has_diss:  # Hunt-Crossley: beta alpha d_r (max(delta, 0) / d_r)**p delta'
        d = _clip(delta)
        if p[_EXPO] != 1.0:
            d = p[_DR] * (d / p[_DR]) ** p[_EXPO]
        fpot = fpot + p[_HCG] * d * dd
    fc = fpot if contact else 0.0
    base = f_t - p[_XI2] * v - x - fc
    total = base
    fk = 0.0
    if friction:
        fk = -total if mode == STUCK else math.copysign(p[_MUK], -0.5 - mode)
        total = total + fk
    dy[0] = v
    dy[1] = total
    if restraint:
        dy[2] = y[3]
        dy[3] = (fc - p[_KAPPA] * y[2] - p[_RDAMP] * y[3]) / p[_MU]
    for j in range(n_face):  # LearnedContact.state_derivative: rows without a mode rest
        col, s = _FACE + len(_MODE_KEYS) * j, 2 + 2 * j
        if p[col] != 0.0:
            dy[s] = y[s + 1]
            dy[s + 1] = (fc - p[col + 2] * y[s] - p[col + 3] * y[s + 1]) / p[col + 1]
        else:
            dy[s], dy[s + 1] = 0.0, 0.0
    if learned:  # a scaled face's beta state: held
        for c in range(2 + 2 * n_face, dy.shape[0]):
            dy[c] = 0.0
    return delta, dd, fpot, base, total, fk


@_jit_inline
def _rk4_row(p, t, y, k1, s, contact, mode, has_gap, has_cc, hertz, friction, restraint,
             n_forcing, n_gap, learned, n_face, has_pre, has_diss, out, k2, k3, k4,
             tmp):  # fmt: skip
    """:func:`~stiffnet.simulator.rk4._rk4` for one row: its state after a step of length
    ``s`` into ``out``, its stages into ``k2, k3, k4`` (``tmp``: scratch of the state's
    size)."""
    n_y = y.shape[0]
    half = 0.5 * s
    tm = t + half
    fm = _sines(p, _FORCING, n_forcing, tm, False)
    for c in range(n_y):
        tmp[c] = y[c] + half * k1[c]
    _rhs(p, tm, tmp, contact, mode, fm, has_gap, has_cc, hertz, friction, restraint,
         n_gap, learned, n_face, has_pre, has_diss, k2)  # fmt: skip
    for c in range(n_y):
        tmp[c] = y[c] + half * k2[c]
    _rhs(p, tm, tmp, contact, mode, fm, has_gap, has_cc, hertz, friction, restraint,
         n_gap, learned, n_face, has_pre, has_diss, k3)  # fmt: skip
    for c in range(n_y):
        tmp[c] = y[c] + s * k3[c]
    t4 = t + s
    f4 = _sines(p, _FORCING, n_forcing, t4, False)
    _rhs(p, t4, tmp, contact, mode, f4, has_gap, has_cc, hertz, friction, restraint,
         n_gap, learned, n_face, has_pre, has_diss, k4)  # fmt: skip
    w = s / 6.0
    for c in range(n_y):
        out[c] = y[c] + w * (k1[c] + 2.0 * (k2[c] + k3[c]) + k4[c])


@_jit
def _rk4_rows(pack, t, y, k1, s, contact, modes, fric, has_gap, has_cc, hertz, restraint,
              n_forcing, n_gap, learned, n_face, out, k2, k3, k4):  # fmt: skip
    """:func:`~stiffnet.simulator.rk4._rk4` row by row, its stages into ``k2, k3, k4``."""
    tmp = np.empty(y.shape[1])
    friction = fric >= 0
    has_pre, has_diss = _learned_flags(pack) if learned else (False, False)
    for i in range(y.shape[0]):
        mode = modes[fric, i] if friction else 0.0
        _rk4_row(pack[i], t[i], y[i], k1[i], s[i], contact[i], mode, has_gap, has_cc, hertz,
                 friction, restraint, n_forcing, n_gap, learned, n_face, has_pre, has_diss,
                 out[i], k2[i], k3[i], k4[i], tmp)  # fmt: skip


def rk4_step(
    form: KernelForm,
    pack: np.ndarray,
    has_gap: bool,
    has_cc: bool,
    t: np.ndarray,
    y: np.ndarray,
    k1: np.ndarray,
    s: np.ndarray,
    contact: np.ndarray,
    modes: np.ndarray,
) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
    """One classical RK4 step of length ``s`` (per row) from ``(t, y)`` with ``k1 = f(t,
    y)``, and its stages ``(k1, k2, k3, k4)``: bitwise :func:`~stiffnet.simulator.rk4.
    _rk4_dense`'s. ``has_gap``, ``has_cc``: the model's flags for these rows."""
    # the event locator hands views and column selections: one layout, one compilation
    y, k1 = np.ascontiguousarray(y, dtype=float), np.ascontiguousarray(k1, dtype=float)
    modes = np.ascontiguousarray(modes, dtype=float)
    out = np.empty_like(y)
    k2, k3, k4 = np.empty_like(y), np.empty_like(y), np.empty_like(y)
    _rk4_rows(
        pack, np.ascontiguousarray(t, dtype=float), y, k1, np.ascontiguousarray(s, dtype=float),
        np.ascontiguousarray(contact, dtype=np.bool_), modes, form.friction, has_gap, has_cc,
        form.hertz, form.restraint, form.n_forcing, form.n_gap, form.learned, form.n_face,
        out, k2, k3, k4,
    )  # fmt: skip
    return out, (k1, k2, k3, k4)


#: The rows of :func:`rhs_full`'s block of switching data, by ``aux`` key.
AUX_ROWS = ("G", "Gr", "dd", "delta", "fc", "extra")


@_jit_inline
def _aux_row(p, t, y, contact, mode, fric, has_gap, has_cc, hertz, restraint, n_forcing,
             n_gap, learned, n_face, has_pre, has_diss, dy, block, i, other, g):  # fmt: skip
    """``_Model.rhs(full=True)`` for one row: dy/dt into ``dy``, the switching data into
    column ``i`` of ``block`` (:data:`AUX_ROWS`), ``other`` (n_effects,) and ``g`` (1 with
    friction)."""
    friction = fric >= 0
    f_t = _sines(p, _FORCING, n_forcing, t, False)
    delta, dd, fpot, base, total, fk = _rhs(
        p, t, y, contact, mode, f_t, has_gap, has_cc, hertz, friction,
        restraint, n_gap, learned, n_face, has_pre, has_diss, dy,
    )  # fmt: skip
    g_contact = delta if (delta < fpot or delta != delta) else fpot  # np.minimum
    # the root function: G where contact damping acts on the row, else delta; with a
    # law that has a penetration-dependent dissipation hook (the learned one, whether or
    # not its term is on), G while the mass leaves, else delta
    if learned:
        block[1, i] = g_contact if dd < 0 else delta
    else:
        block[1, i] = (g_contact if p[_CC] != 0 else delta) if has_cc else delta
    block[0, i] = g_contact
    block[2, i], block[3, i] = dd, delta
    pos = fpot if (fpot > 0.0 or fpot != fpot) else 0.0  # np.maximum(fpot, 0)
    block[4, i] = pos if contact else 0.0
    block[5, i] = total - base
    for k in range(other.shape[0]):
        other[k] = total
    if friction:
        other[fric] = total - fk  # the total less the effect's own force
        if mode == STUCK:
            g[0] = p[_MUS] - abs(other[fric])
        else:
            g[0] = math.copysign(1.0, mode + 0.5) * y[1]


@_jit
def _rhs_rows(pack, t, y, contact, modes, fric, has_gap, has_cc, hertz, restraint,
              n_forcing, n_gap, learned, n_face, dy, block, other, g):  # fmt: skip
    """``_Model.rhs(full=True)`` row by row: dy/dt into ``dy``, the switching data into
    ``block`` (:data:`AUX_ROWS`), ``other`` (B, n_effects) and ``g`` (B, 1 with friction)."""
    friction = fric >= 0
    has_pre, has_diss = _learned_flags(pack) if learned else (False, False)
    for i in range(y.shape[0]):
        mode = modes[fric, i] if friction else 0.0
        _aux_row(pack[i], t[i], y[i], contact[i], mode, fric, has_gap, has_cc, hertz,
                 restraint, n_forcing, n_gap, learned, n_face, has_pre, has_diss, dy[i],
                 block, i, other[i], g[i])  # fmt: skip


def rhs_full(
    form: KernelForm,
    pack: np.ndarray,
    has_gap: bool,
    has_cc: bool,
    n_effects: int,
    t: np.ndarray,
    y: np.ndarray,
    contact: np.ndarray,
    modes: np.ndarray,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """``_Model.rhs(t, y, contact, modes, full=True)`` by the kernel: dy/dt and ``aux``,
    bitwise the numpy path's."""
    n = y.shape[0]
    dy = np.empty((n, y.shape[1]))
    block = np.empty((len(AUX_ROWS), n))
    other = np.empty((n, n_effects))
    g = np.empty((n, 1 if form.friction >= 0 else 0))
    _rhs_rows(
        pack, np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(y, dtype=float),
        np.ascontiguousarray(contact, dtype=np.bool_), np.ascontiguousarray(modes, dtype=float),
        form.friction, has_gap, has_cc, form.hertz, form.restraint, form.n_forcing,
        form.n_gap, form.learned, form.n_face, dy, block, other, g,
    )  # fmt: skip
    aux = dict(zip(AUX_ROWS, block, strict=True))
    aux["other"], aux["g"] = other, g
    return dy, aux


@_jit
def _substep_rows(pack, t, y, k1, s, t1, contact, modes, fric, has_gap, has_cc, hertz,
                  restraint, n_forcing, n_gap, learned, n_face, delta0, dd0, out, dy, block,
                  other, g, suspect):  # fmt: skip
    """One substep of the march, row by row: :func:`_rk4_row` into ``out``, the right-hand
    side and switching data at ``(t1, out)`` (:func:`_aux_row`) and whether the row must be
    resolved (``_Stepper._suspects``: the contact or an event function changed sign, or the
    penetration turned near the restraint; ``delta0``, ``dd0``: the substep's start)."""
    n_y = y.shape[1]
    k2, k3, k4, tmp = np.empty(n_y), np.empty(n_y), np.empty(n_y), np.empty(n_y)
    friction = fric >= 0
    has_pre, has_diss = _learned_flags(pack) if learned else (False, False)
    for i in range(y.shape[0]):
        mode = modes[fric, i] if friction else 0.0
        _rk4_row(pack[i], t[i], y[i], k1[i], s[i], contact[i], mode, has_gap, has_cc, hertz,
                 friction, restraint, n_forcing, n_gap, learned, n_face, has_pre, has_diss,
                 out[i], k2, k3, k4, tmp)  # fmt: skip
        _aux_row(pack[i], t1[i], out[i], contact[i], mode, fric, has_gap, has_cc, hertz,
                 restraint, n_forcing, n_gap, learned, n_face, has_pre, has_diss, dy[i],
                 block, i, other[i], g[i])  # fmt: skip
        crossed = (block[0, i] > 0.0) != contact[i]
        for j in range(g.shape[1]):
            crossed = crossed or g[i, j] <= 0.0
        d0, d1, r0, r1 = delta0[i], block[3, i], dd0[i], block[2, i]
        span = (abs(r0) + abs(r1)) * s[i]
        nan = d0 != d0 or d1 != d1  # np.maximum and np.minimum propagate NaN
        hi = math.nan if nan else (d0 if d0 >= d1 else d1)
        lo = math.nan if nan else (d0 if d0 <= d1 else d1)
        turn_free = (not contact[i]) and r0 > 0.0 and r1 <= 0.0 and hi + span > 0.0
        turn_con = contact[i] and r0 < 0.0 and r1 >= 0.0 and lo - span < 0.0
        suspect[i] = crossed or turn_free or turn_con


def substep(
    form: KernelForm,
    pack: np.ndarray,
    has_gap: bool,
    has_cc: bool,
    n_effects: int,
    t: np.ndarray,
    y: np.ndarray,
    k1: np.ndarray,
    s: np.ndarray,
    t1: np.ndarray,
    contact: np.ndarray,
    modes: np.ndarray,
    aux0: dict[str, np.ndarray],
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """One substep of ``_Stepper.march`` in one compiled call: the RK4 step of length ``s``
    from ``(t, y)`` (:func:`rk4_step`'s state), the right-hand side and ``aux`` at ``(t1,
    state)`` (:func:`rhs_full`'s) and the rows to resolve (``_Stepper._suspects``' indices,
    from ``aux0``, the switching data at ``(t, y)``), bitwise the three calls' numbers.

    The march takes a substep at a time on the whole batch, and on a batch of tens of rows
    the three calls' wrapping, allocations and numpy passes cost as much as the arithmetic.
    """
    n = y.shape[0]
    out = np.empty((n, y.shape[1]))
    dy = np.empty_like(out)
    block = np.empty((len(AUX_ROWS), n))
    other = np.empty((n, n_effects))
    g = np.empty((n, 1 if form.friction >= 0 else 0))
    suspect = np.empty(n, dtype=np.bool_)
    _substep_rows(
        pack, np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(y, dtype=float),
        np.ascontiguousarray(k1, dtype=float), np.ascontiguousarray(s, dtype=float),
        np.ascontiguousarray(t1, dtype=float), np.ascontiguousarray(contact, dtype=np.bool_),
        np.ascontiguousarray(modes, dtype=float), form.friction, has_gap, has_cc, form.hertz,
        form.restraint, form.n_forcing, form.n_gap, form.learned, form.n_face,
        np.ascontiguousarray(aux0["delta"], dtype=float),
        np.ascontiguousarray(aux0["dd"], dtype=float), out, dy, block, other, g, suspect,
    )  # fmt: skip
    aux = dict(zip(AUX_ROWS, block, strict=True))
    aux["other"], aux["g"] = other, g
    return out, dy, aux, suspect.nonzero()[0]


#: What :func:`secant_row` locates the root of: a row of ``aux``'s block
#: (:data:`AUX_ROWS`) by its key, or an effect's event function (``aux["g"]``'s column).
SECANT_KEYS = {key: k for k, key in enumerate(AUX_ROWS)}
_EVENT_KEY = -1


@_jit
def _sign(x):
    """``np.sign`` of a float (NaN propagated; the sign of a zero is irrelevant where it is
    used: a product with it is never positive)."""
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else x)


@_jit
def _secant_rows(pack, t, y, k1, contact, modes, fric, has_gap, has_cc, hertz, restraint,
                 n_forcing, n_gap, learned, n_face, n_effects, key, col, hi, glo, ghi, tol,
                 iters, tiny, s_seen, y_seen):  # fmt: skip
    """The event locator's secant (``events._illinois``) on RK4 partial steps of the rows
    of ``pack`` from ``(t, y)`` with ``k1 = f(t, y)``: the root function is ``aux``'s block
    row ``key`` at the partial step's state, or with ``key`` < 0 the event function ``col``.

    The same IEEE operations in the same order as the vectorised loop, row by row: every
    pass evaluates every row (a converged row at the far end of its bracket, as numpy's
    loop does), each evaluation the kernel's :func:`_rk4_row` then :func:`_aux_row` with
    the model's row-wide flags (bitwise the numbers of ``_Partial.aux``). The roots (the far
    ends of the final brackets) are left in ``hi``; each pass's step lengths and states go
    into ``s_seen`` (passes, R) and ``y_seen`` (passes, R, n_y). Returns the passes."""
    friction = fric >= 0
    has_pre, has_diss = _learned_flags(pack) if learned else (False, False)
    n_rows, n_y = y.shape
    k2, k3, k4 = np.empty(n_y), np.empty(n_y), np.empty(n_y)
    tmp, dy = np.empty(n_y), np.empty(n_y)
    block = np.empty((len(AUX_ROWS), 1))
    other = np.empty(n_effects)
    g = np.empty(1 if friction else 0)
    lo = np.zeros(n_rows)
    last = np.zeros(n_rows, dtype=np.int8)  # -1: lo moved last, +1: hi moved last
    sgn = np.empty(n_rows)
    for i in range(n_rows):
        sgn[i] = _sign(glo[i])
    live = np.empty(n_rows, dtype=np.bool_)
    for n in range(iters):
        any_live = False
        for i in range(n_rows):
            live[i] = hi[i] - lo[i] > tol[i] and ghi[i] != 0.0
            any_live = any_live or live[i]
        if not any_live:
            return n
        for i in range(n_rows):
            if live[i]:
                s = lo[i] - glo[i] * (hi[i] - lo[i]) / (ghi[i] - glo[i])
                if not math.isfinite(s) or s <= lo[i] or s >= hi[i] or abs(glo[i]) <= tiny:
                    s = 0.5 * (lo[i] + hi[i])
            else:
                s = hi[i]
            mode = modes[fric, i] if friction else 0.0
            ys = y_seen[n, i]
            _rk4_row(pack[i], t[i], y[i], k1[i], s, contact[i], mode, has_gap, has_cc, hertz,
                     friction, restraint, n_forcing, n_gap, learned, n_face, has_pre,
                     has_diss, ys, k2, k3, k4, tmp)  # fmt: skip
            s_seen[n, i] = s
            _aux_row(pack[i], t[i] + s, ys, contact[i], mode, fric, has_gap, has_cc, hertz,
                     restraint, n_forcing, n_gap, learned, n_face, has_pre, has_diss, dy,
                     block, 0, other, g)  # fmt: skip
            if not live[i]:
                continue
            val = g[col] if key < 0 else block[key, 0]
            if val * sgn[i] > 0:
                if last[i] == -1:
                    ghi[i] = 0.5 * ghi[i]
                lo[i], glo[i], last[i] = s, val, -1
            else:
                if last[i] == 1:
                    glo[i] = 0.5 * glo[i]
                hi[i], ghi[i], last[i] = s, val, 1
    return iters


def secant_rows(
    form: KernelForm,
    pack: np.ndarray,
    has_gap: bool,
    has_cc: bool,
    n_effects: int,
    start: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    root: str | int,
    bracket: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    iters: int,
    tiny: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Roots of the rows' switching function on RK4 partial steps, by the event locator's
    Illinois secant compiled with its evaluations (:func:`_secant_rows`).

    Parameters
    ----------
    form, pack, has_gap, has_cc, n_effects
        The rows' model's kernel (``_Model.kernel``, its pack and flags).
    start
        ``(t, y, k1, contact, modes)`` of the R rows, (R,), (R, n_y), (R, n_y), (R,),
        (n_effects, R): the partial steps start there.
    root
        The root function: ``aux``'s key (:data:`SECANT_KEYS`), or ``j`` for the model's
        event function ``j`` (``aux["g"][:, j]``).
    bracket
        ``(hi, g(0), g(hi), tol)``, (R,) each, as ``events._illinois`` takes them.
    iters, tiny
        The secant's iteration cap and its boundary threshold (``events``' constants).

    Returns
    -------
    tuple
        The roots (R,), and each pass's step lengths (passes, R) and states
        (passes, R, n_y), in the order they were computed.
    """
    t, y, k1, contact, modes = start
    k, col = (SECANT_KEYS[root], 0) if isinstance(root, str) else (_EVENT_KEY, root)
    n_rows = y.shape[0]
    s_seen, y_seen = np.empty((iters, n_rows)), np.empty((iters, n_rows, y.shape[1]))
    hi, glo, ghi, tol = (np.array(v, dtype=float) for v in bracket)  # copies: updated in place
    n = _secant_rows(
        pack, np.ascontiguousarray(t, dtype=float), np.ascontiguousarray(y, dtype=float),
        np.ascontiguousarray(k1, dtype=float), np.ascontiguousarray(contact, dtype=np.bool_),
        np.ascontiguousarray(modes, dtype=float), form.friction, has_gap, has_cc, form.hertz,
        form.restraint, form.n_forcing, form.n_gap, form.learned, form.n_face, n_effects, k,
        col, hi, glo, ghi, tol, iters, tiny, s_seen, y_seen,
    )  # fmt: skip
    return hi, s_seen[:n], y_seen[:n]
