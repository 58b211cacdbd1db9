r"""The ``face`` term: a restraint whose contact face has its own mass (a mode of its own).

A restraint with its own dynamics (a beam's tip, a tool holder: the library's
``restraint_mass``) is not a function of the present penetration and its rate:
the force depends on the impact's history. The discovery models it the way the
physics is built, a face of mass ``mu`` (over the mass m) on a support of
stiffness ``kappa`` with damping ratio ``zeta``, pushed by the contact force::

    mu y'' + 2 zeta sqrt(kappa mu) y' + kappa y = F_c(t)
    F_c = beta shape(x - e - y, v - y')           (the contact law acts on the face)

Given the measured force of an impact, the face's recoil ``y`` (and ``y'``) is the
force filtered by this mode: an exact discretisation of the linear ODE with the
force linear between samples (first-order hold: the matrix exponential of the state augmented
with the force and its slope),
from rest at the impact's first sample (the samples start before the touch), plus the
free ringing it inherits from the impacts before it where the samples carry their
indices in the record (:func:`ringing_from_before`). The law's
residual is then the equation error ``F - beta shape(x - e - y)``, as in an
ARX model whose lagged terms are the force's own history, but with physical
parameters (the face's mass, support stiffness and damping), so the learned law
runs in the simulator as states of ``learned_contact`` with exact contact events.

A restraint with several modes (a beam's tip: its bending modes in parallel at the tip,
each a modal mass on its modal stiffness, the tip's recoil their sum) is the ``face2`` term
on top of ``face``: a second mode ``mu_2 y_2'' + 2 zeta_2 sqrt(kappa_2 mu_2) y_2' +
kappa_2 y_2 = F_c`` driven by the same force, its own exact discretisation, and the law
acting on ``x - e - y - y_2``. Its starts sit above the first mode
(:func:`second_mode_starts`), where a cantilever's second mode is.

The sampling interval in model time is not carried by the samples: it is read
from them (:func:`sample_interval`), since the map's displacement is the integral
of its velocity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy import linalg

#: Shared parameters of the term: name, lower and upper bound, starting value.
FACE_PARAMS = (
    ("face_mass", 1e-3, 10.0, 0.3),
    ("face_stiffness", 0.3, 1e4, 40.0),
    ("face_damping", 0.0, 1.0, 0.1),
)
#: The second mode's parameters (``face2``, only on top of ``face``): a beam's second mode is
#: stiffer than the first by its frequency ratio squared (39 for a cantilever).
FACE2_PARAMS = (
    ("face2_mass", 1e-3, 10.0, 0.1),
    ("face2_stiffness", 0.3, 1e5, 400.0),
    ("face2_damping", 0.0, 1.0, 0.05),
)
#: The second mode's starts: its frequency over the first's (a cantilever's 6.27, and lower
#: for a support that is not clamped) and its mass over the first's.
SECOND_FREQUENCY_STARTS = (2.5, 6.3)
SECOND_MASS_STARTS = (0.5, 1.0)
#: Support stiffnesses tried as starts, as multiples of the campaign's median beta (a face
#: much stiffer than the contact is invisible; one much softer dominates the series spring).
STIFFNESS_STARTS = (0.6, 1.5, 4.0)
#: Face frequencies tried as starts with each stiffness, as multiples of the fastest contact
#: frequency ``sqrt(1 + beta)`` of the campaign. The restoring-force betas are the contact in
#: series with the support, so a soft support (a beam's tip) reads them low and puts its face
#: several times above them (4.0: on a cantilever of mass 0.4 ringing at 10 natural
#: frequencies the maps read beta 4-6.5 for 8-90, and the face rings at 3.7 times the
#: fastest reading).
FREQUENCY_STARTS = (0.7, 1.5, 4.0)


def sample_interval(x: np.ndarray, v: np.ndarray, impact: np.ndarray) -> float:
    """The sampling interval in model time, from ``dx = v dt`` within each impact (LSQ)."""
    dx = np.diff(x)
    vm = 0.5 * (v[1:] + v[:-1])
    same = np.diff(impact) == 0
    den = float(np.sum(vm[same] ** 2))
    return float(np.sum(dx[same] * vm[same]) / den) if den > 0 else 0.0


@dataclass(frozen=True)
class Layout:
    """Where each sample sits in an (impact, time) padded array, and each impact's recording."""

    row: np.ndarray  # impact row of each sample
    col: np.ndarray  # time column of each sample
    rec: np.ndarray  # recording of each impact row
    shape: tuple[int, int]


def layout(rec: np.ndarray, impact: np.ndarray, n_rec: int) -> Layout:
    """The padded layout of samples ordered by time within contiguous impacts."""
    if impact.size == 0:
        return Layout(impact, impact, impact, (0, 0))
    start = np.r_[True, (np.diff(impact) != 0) | (np.diff(rec) != 0)]
    row = np.cumsum(start) - 1
    first = np.flatnonzero(start)
    col = np.arange(impact.size) - first[row]
    return Layout(row, col, rec[first], (int(row[-1]) + 1, int(col.max()) + 1))


def face_transition(mass: float, stiffness: float, damping: float, dts: np.ndarray) -> np.ndarray:
    """The exact one-step map of the face's state under a force linear between samples.

    Returns ``E`` (R, 4, 4) ``= expm(M dt)`` for the augmented state ``(y, y', F, F')``
    (``F'`` constant over the step): ``(y, y')_{k+1} = E[:2, :2] (y, y')_k + E[:2, 2] F_k
    + E[:2, 3] (F_{k+1} - F_k) / dt``, per recording's interval ``dt``.
    """
    w2 = stiffness / mass
    m = np.zeros((4, 4))
    m[0, 1] = 1.0
    m[1, 0], m[1, 1], m[1, 2] = -w2, -2.0 * damping * np.sqrt(w2), 1.0 / mass
    m[2, 3] = 1.0
    return linalg.expm(np.asarray(dts, float)[:, None, None] * m)


def face_transitions(
    mass: np.ndarray, stiffness: np.ndarray, damping: float, dts: np.ndarray
) -> np.ndarray:
    """:func:`face_transition` of one face per recording, (R, 4, 4): recording ``r``'s face
    (``mass[r]``, ``stiffness[r]``) at its interval ``dts[r]``, in one ``expm`` of the stack."""
    mass, stiffness = np.asarray(mass, float), np.asarray(stiffness, float)
    w2 = stiffness / mass
    m = np.zeros((mass.size, 4, 4))
    m[:, 0, 1] = 1.0
    m[:, 1, 0], m[:, 1, 1], m[:, 1, 2] = -w2, -2.0 * damping * np.sqrt(w2), 1.0 / mass
    m[:, 2, 3] = 1.0
    return linalg.expm(np.asarray(dts, float)[:, None, None] * m)


def force_drive(force: np.ndarray, lay: Layout, dts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The force and its slope to the next sample on the padded impacts, (I, C) each: what
    drives the face (:func:`face_transition`'s ``F`` and ``F'``)."""
    u = np.zeros(lay.shape)
    u[lay.row, lay.col] = force
    du = np.zeros(lay.shape)
    du[:, :-1] = np.diff(u, axis=1) / np.asarray(dts, float)[lay.rec][:, None]
    return u, du


def face_response(
    force: np.ndarray,
    lay: Layout,
    dts: np.ndarray,
    mass: float | np.ndarray,
    stiffness: float | np.ndarray,
    damping: float,
    index: np.ndarray | None = None,
    chain: ImpactChain | None = None,
    drive: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The face's recoil and its rate on every sample, driven by the measured force, (N,) each.

    Parameters
    ----------
    force : numpy.ndarray
        Contact force on every sample (model units).
    lay : Layout
        The samples' impacts (:func:`layout`).
    dts : numpy.ndarray
        Each recording's sampling interval in model time.
    mass, stiffness, damping : float
        ``mu``, ``kappa``, ``zeta`` of the face (see the module notes); ``mass`` and
        ``stiffness`` may be arrays (R,), each recording's own face (:mod:`.face_scaled`).
    index : numpy.ndarray, optional
        Each sample's index in its record: the face then carries its ringing from one
        impact into the next (:func:`ringing_from_before`); without, each starts at rest.
    chain : ImpactChain, optional
        :func:`impact_chain` of ``lay``, ``index`` and ``dts``, where already built (it
        depends on the samples, not on the face; it stands for ``index``).
    drive : tuple of numpy.ndarray, optional
        :func:`force_drive` of ``force``, where already built (it depends on the force alone).
    """
    if force.size == 0:
        return np.zeros(0), np.zeros(0)
    if np.ndim(mass) > 0:  # a face per recording, all filtered at once
        e = face_transitions(mass, stiffness, damping, dts)[lay.rec]
    else:
        # one map per distinct interval (a campaign has few; scipy's expm was a third of a face)
        steps, of_rec = np.unique(np.asarray(dts, float), return_inverse=True)
        e = face_transition(mass, stiffness, damping, steps)[of_rec.reshape(-1)[lay.rec]]
    u, du = force_drive(force, lay, dts) if drive is None else drive
    y, yd = response_from_rest(np.ascontiguousarray(e), u, du)
    if chain is None and index is not None and index.size == force.size:
        chain = impact_chain(lay, index, dts)
    if chain is not None:
        free = ringing_from_before(y, yd, chain, mass, stiffness, damping, lay.rec)
        y, yd = y + free[..., 0], yd + free[..., 1]
    return y[lay.row, lay.col], yd[lay.row, lay.col]


# The two recursions below are the face's exact discrete steps, one sample (or one impact)
# at a time: each step's state is the last one's, so they cannot be vectorised along time.
# Compiled, with the arithmetic written in numpy's order (``a * s0 + b * s1 + c * u + d * du``
# summed left to right, no fused multiply-add): the same bits as the array expressions they
# replaced, which looped in Python over every column, so the fitted laws do not move.
@numba.njit(cache=True, error_model="numpy")
def response_from_rest(
    e: np.ndarray, u: np.ndarray, du: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """The face's state on every padded sample from rest at each impact's first, (I, C) each.

    ``e`` (I, 4, 4): each impact's one-step map (:func:`face_transition`); ``u``, ``du``
    (I, C): the force and its slope per sample. State ``s_k`` before the step at ``k``,
    ``s_{k+1} = E[:2, :2] s_k + E[:2, 2] u_k + E[:2, 3] du_k``.
    """
    n_imp, n_col = u.shape
    y = np.zeros((n_imp, n_col))
    yd = np.zeros((n_imp, n_col))
    for i in range(n_imp):
        p00, p01, p10, p11 = e[i, 0, 0], e[i, 0, 1], e[i, 1, 0], e[i, 1, 1]
        g0, g1, h0, h1 = e[i, 0, 2], e[i, 1, 2], e[i, 0, 3], e[i, 1, 3]
        s0 = 0.0
        s1 = 0.0
        for k in range(n_col):
            y[i, k] = s0
            yd[i, k] = s1
            uk, dk = u[i, k], du[i, k]
            n0 = p00 * s0 + p01 * s1 + g0 * uk + h0 * dk
            n1 = p10 * s0 + p11 * s1 + g1 * uk + h1 * dk
            s0, s1 = n0, n1
    return y, yd


@numba.njit(cache=True, error_model="numpy")
def carried_states(m: np.ndarray, b: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """The state each impact starts in, (R, P, 2): ``s_k = m_k s_{k-1} + b_k`` along each
    recording's impacts (``m`` (R, P, 2, 2), ``b`` (R, P, 2)), from zero at the first."""
    n_rec, n_place = b.shape[0], b.shape[1]
    states = np.zeros((n_rec, n_place, 2))
    for r in range(n_rec):
        s0 = 0.0
        s1 = 0.0
        for k in range(1, n_place):
            n0 = m[r, k, 0, 0] * s0 + m[r, k, 0, 1] * s1 + b[r, k, 0]
            n1 = m[r, k, 1, 0] * s0 + m[r, k, 1, 1] * s1 + b[r, k, 1]
            s0, s1 = n0, n1
            states[r, k, 0] = s0
            states[r, k, 1] = s1
    return states


def free_map(gap: np.ndarray, w2: float | np.ndarray, damping: float) -> np.ndarray:
    """``expm(A t)`` of the free face, ``A = [[0, 1], [-w2, -2 zeta sqrt(w2)]]``, (T, 2, 2).

    In closed form (scipy's ``expm`` of a stack of 2 x 2 matrices loops over them in Python,
    and the discovery evaluates thousands of gaps per fit): with ``sigma = zeta w`` and
    ``wd = w sqrt(1 - zeta^2)``, ``e^{-sigma t}`` times ``[[cos + sigma sin / wd, sin / wd],
    [-w2 sin / wd, cos - sigma sin / wd]]``; overdamped, the sines are hyperbolic (written
    with both exponents combined, so that nothing overflows where the product does not); at
    critical damping ``sin(wd t) / wd`` is ``t`` in the limit. ``w2`` may be one per gap.
    """
    dc, ds, sigma = free_parts(gap, w2, damping)
    out = np.empty(dc.shape + (2, 2))
    out[..., 0, 0] = dc + sigma * ds
    out[..., 0, 1] = ds
    out[..., 1, 0] = -w2 * ds
    out[..., 1, 1] = dc - sigma * ds
    return out


def free_parts(
    t: np.ndarray, w2: float | np.ndarray, damping: float
) -> tuple[np.ndarray, np.ndarray, float | np.ndarray]:
    """:func:`free_map`'s ingredients at the times ``t``: ``e^{-sigma t} cos(wd t)``,
    ``e^{-sigma t} sin(wd t) / wd`` (hyperbolic when overdamped) and ``sigma`` (``w2``: one,
    or an array that broadcasts with ``t``, one face per row)."""
    t = np.asarray(t, float)
    w = np.sqrt(w2)
    sigma = damping * w
    a = w * np.sqrt(abs(1.0 - damping * damping))
    # max(a t) is a max(t) for one face (rounding keeps the order), the largest for many
    if float(np.max(a * t, initial=0.0)) < 1e-6:  # critical: the series' first terms
        dc = np.exp(-sigma * t)
        ds = dc * t
    elif damping < 1.0:
        decay = np.exp(-sigma * t)
        dc, ds = decay * np.cos(a * t), decay * np.sin(a * t) / a
    else:
        slow, fast = np.exp((a - sigma) * t), np.exp(-(a + sigma) * t)
        dc, ds = 0.5 * (slow + fast), 0.5 * (slow - fast) / a
    return dc, ds, sigma


@dataclass(frozen=True)
class ImpactChain:
    """What the ringing carried between impacts needs of the samples alone (not of the face):
    built once per campaign (:func:`impact_chain`) and shared by every face it filters."""

    dt: np.ndarray  # (I,) each impact's sampling interval
    gap: np.ndarray  # (I - 1,) time from each impact's last sample to the next one's first
    same_rec: np.ndarray  # (I - 1,) the next impact is of the same recording
    length: np.ndarray  # (I,) each impact's last column
    through_t: np.ndarray  # (I,) time over each impact's own samples
    grid: np.ndarray  # (R, P) impacts by recording and place, -1 where none
    on: np.ndarray  # (R, P) an impact after another of its recording
    prev: np.ndarray  # (R, P) the impact before it (0 where none)
    #: (U, C) a padded sample's time since its impact's first, per distinct sampling interval:
    #: the free map at those times is the same for every impact of that interval
    times: np.ndarray
    interval: np.ndarray  # (I,) each impact's row of ``times``


def impact_chain(lay: Layout, index: np.ndarray, dts: np.ndarray) -> ImpactChain:
    """The :class:`ImpactChain` of samples laid out as ``lay`` with record indices ``index``."""
    n_imp, n_col = lay.shape
    first = np.flatnonzero(lay.col == 0)
    last = np.r_[first[1:] - 1, index.size - 1]
    dt = np.asarray(dts, float)[lay.rec]
    steps, interval = np.unique(dt, return_inverse=True)
    length = lay.col[last]
    rows = np.arange(n_imp)
    new_rec = np.r_[True, lay.rec[1:] != lay.rec[:-1]]
    place = rows - np.maximum.accumulate(np.where(new_rec, rows, 0))
    grid = np.full((int(new_rec.sum()), int(place.max(initial=0)) + 1), -1)
    grid[np.cumsum(new_rec) - 1, place] = rows
    on = grid > 0
    return ImpactChain(
        dt, (index[first[1:]] - index[last[:-1]]) * dt[1:], lay.rec[1:] == lay.rec[:-1],
        length, length * dt, grid, on, np.where(on, grid - 1, 0),
        steps[:, None] * np.arange(n_col), interval.reshape(-1),
    )  # fmt: skip


def ringing_from_before(
    y: np.ndarray, yd: np.ndarray, chain: ImpactChain, mass: float | np.ndarray,
    stiffness: float | np.ndarray, damping: float, face_of: np.ndarray | None = None,
) -> np.ndarray:  # fmt: skip
    """The free ringing each impact inherits from the ones before it, (I, C, 2).

    The face's response is linear: each impact's recoil is its own from rest (``y``, ``yd``)
    plus the free evolution of the state it starts in, which is the previous impact's last
    state rung freely across the samples between them (no contact force there). A tip at
    damping ratio 0.02 ringing at 10 natural frequencies keeps 28 % of its amplitude a
    forcing period later, which starting every impact from rest reads as misfit.
    The free map over ``c`` samples is :func:`free_map` at ``c dt`` (the one-step map's
    ``c``-th power, in closed form: the powers of a stack of 2 x 2 matrices, taken one
    product at a time, were most of a face fit's time). ``mass`` and ``stiffness`` may be
    arrays of faces (F,), ``face_of`` (I,) each impact's: a face per recording
    (:mod:`.face_scaled`).
    """
    c = chain
    per_impact = np.ndim(mass) > 0
    n_face = np.size(mass)
    w2 = stiffness / mass
    if per_impact:
        w2 = np.asarray(w2, float)[face_of]
    gap = c.gap
    w2_gap = w2[:-1] if per_impact else w2  # a gap within a recording: its impacts' face
    # (I - 1, 2, 2) the free map over each gap; a ringing decayed below e^-40 is gone
    across = np.zeros((gap.size, 2, 2))
    alive = (damping * np.sqrt(w2_gap) * gap < 40.0) & c.same_rec
    across[alive] = free_map(gap[alive], w2_gap[alive] if per_impact else w2, damping)
    rows = np.arange(c.length.size)
    own_end = np.stack([y[rows, c.length], yd[rows, c.length]], axis=1)  # (I, 2) from rest
    through = free_map(c.through_t, w2, damping)  # (I, 2, 2) over each impact's own samples
    # impact i starts in  across_i-1 (own_end_i-1 + through_i-1 start_i-1): a linear
    # recursion along each recording (its impacts are contiguous), all recordings at once
    carry = np.einsum("ijk,ikl->ijl", across, through[:-1])  # (I - 1, 2, 2)
    push = np.einsum("ijk,ik->ij", across, own_end[:-1])  # (I - 1, 2)
    m = carry[c.prev] * c.on[..., None, None]  # (R, P, 2, 2); nothing carried where none is
    b = push[c.prev] * c.on[..., None]
    states = carried_states(np.ascontiguousarray(m), np.ascontiguousarray(b))
    start = np.zeros((rows.size, 2))
    start[c.grid[c.on]] = states[c.on]
    # the free map over c samples applied to each start, (I, C) each; the map's entries are
    # those of the impact's sampling interval (a campaign has few: a fifth of a face's
    # filter went to evaluating them on every impact's samples)
    if per_impact:  # each impact's face's map on its interval's times, once per pair
        pair, row = np.unique(c.interval * n_face + face_of, return_inverse=True)
        w2_pair = (np.asarray(stiffness / mass, float)[pair % n_face])[:, None]
        dc, ds, sigma = free_parts(c.times[pair // n_face], w2_pair, damping)
        row = row.reshape(-1)
        a, b, d = (dc + sigma * ds)[row], ds[row], (dc - sigma * ds)[row]
        w2 = w2[:, None]
    else:
        dc, ds, sigma = free_parts(c.times, w2, damping)
        a, b, d = (dc + sigma * ds)[c.interval], ds[c.interval], (dc - sigma * ds)[c.interval]
    s0, s1 = start[:, :1], start[:, 1:]
    return np.stack([a * s0 + b * s1, -w2 * b * s0 + d * s1], -1)


def face_starts(betas: np.ndarray) -> list[dict[str, float]]:
    """Starting faces: support stiffnesses around the contacts' and frequencies around theirs."""
    beta = float(np.median(betas))
    w_top = float(np.sqrt(1.0 + np.max(betas)))
    out = []
    for ks in STIFFNESS_STARTS:
        for fw in FREQUENCY_STARTS:
            kappa = ks * beta
            out.append({"face_stiffness": kappa, "face_mass": kappa / (fw * w_top) ** 2})
    return out


def second_mode_starts(shared: dict[str, float]) -> list[dict[str, float]]:
    """Starting second modes above the fitted first one (``face_mass``, ``face_stiffness``):
    frequencies :data:`SECOND_FREQUENCY_STARTS` times the first's, masses
    :data:`SECOND_MASS_STARTS` times its mass, the damping the first's."""
    mu, kappa = shared["face_mass"], shared["face_stiffness"]
    out = []
    for fr in SECOND_FREQUENCY_STARTS:
        for mr in SECOND_MASS_STARTS:
            m2 = mr * mu
            out.append({"face2_mass": m2, "face2_stiffness": m2 * fr**2 * kappa / mu,
                        "face2_damping": shared.get("face_damping", 0.05)})  # fmt: skip
    return out
