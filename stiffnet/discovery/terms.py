r"""The candidate terms and the joint fit of a law made of some of them.

A law is the ``learned_contact`` effect's (:mod:`stiffnet.effects.learned_contact`),
``F_c = max(0, beta_r shape(x - e_r, v) + 2 zeta_c sqrt(beta_r) v)`` in contact,
with the shape's *terms* shared by every recording and one ``beta_r`` and one
onset ``e_r`` per recording (the rigs differ in stiffness and gap, not in the kind
of contact). The candidate terms, beyond the linear spring ``delta``:

========================  =====================================  =====================
term                      force per unit beta                    shared parameters
========================  =====================================  =====================
``power``                 ``d_r (delta / d_r)**p`` (replaces     ``exponent`` p
                          ``delta``)
``hinge``                 ``(r - 1) max(delta - delta_k, 0)``    ``knee``, ``knee_ratio``
``damping``               ``2 zeta_c v / sqrt(beta)``            ``damping_ratio``
                          (Kelvin-Voigt)
``hunt_crossley``         ``alpha d_r (delta / d_r)**p v``       ``hunt_crossley``
``preload``               ``delta + delta_0`` in the leading     ``preload``
                          term (compressed before touch)
``face``                  the law acts on ``delta - y``, ``y``   ``face_mass``,
                          the recoil of a face with its own      ``face_stiffness``,
                          mass (:mod:`.face`)                    ``face_damping``
``face2``                 the face's second mode: ``y`` is the   ``face2_mass``,
                          sum of both modes' recoils (only on    ``face2_stiffness``,
                          top of ``face``)                       ``face2_damping``
``face_scaled``           a face that is each recording's own:   ``face_mass``,
                          support ``r beta``, mass scaling as    ``face_stiffness_ratio``,
                          ``beta^q``, the contact ``r/(r-1)``    ``face_damping``,
                          beta in front (:mod:`.face_scaled`;    ``face_mass_exponent``
                          not with ``face``)
========================  =====================================  =====================

``d_r`` is fixed (the campaign's median peak penetration, rounded), not fitted:
it only sets where a power law's beta is read. The fit is one bounded
nonlinear least squares (scipy's ``least_squares``) over the samples near the
impacts with the release rule (the force is clipped at zero), each recording's
residuals scaled by its own force scale so every recording counts alike; its
Jacobian's sparsity (a recording's beta and onset touch only its samples) keeps
it to a few residual evaluations per step.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy import optimize, sparse

from stiffnet.discovery.face import (
    FACE2_PARAMS,
    FACE_PARAMS,
    ImpactChain,
    Layout,
    face_response,
    force_drive,
    impact_chain,
    layout,
    sample_interval,
)
from stiffnet.discovery.face_scaled import SCALED_PARAMS, reference_beta, scaled_face_recoil
from stiffnet.discovery.samples import ContactSamples
from stiffnet.effects.learned_contact import NEUTRAL, learned_contact_force

#: Candidate terms beyond the linear spring, in the order they are tried.
TERMS = ("power", "hinge", "damping", "hunt_crossley", "preload", "face", "face2", "face_scaled")
#: The face's modes, each a term whose parameters are ``MODE_mass``/``_stiffness``/``_damping``.
FACE_MODES = ("face", "face2")
#: Terms that are a face (the shared one's modes, the scaled one): the scaled face is never
#: in a law with the shared one.
FACE_TERMS = ("face", "face2", "face_scaled")
#: Terms of the library's own laws (``contact_damping``); ``hertz`` is ``power`` at 3/2.
LIBRARY_TERMS = frozenset({"damping", "hertz"})
#: Shared parameters of each term, with their bounds and starting value.
TERM_PARAMS: dict[str, tuple[tuple[str, float, float, float], ...]] = {
    "power": (("exponent", 0.6, 4.0, 1.5),),
    "hinge": (("knee", 1e-3, 10.0, 0.1), ("knee_ratio", 0.05, 50.0, 3.0)),
    "damping": (("damping_ratio", 0.0, 1.5, 0.1),),
    "hunt_crossley": (("hunt_crossley", 0.0, 50.0, 0.3),),
    "preload": (("preload", -0.5, 0.5, 0.0),),
    "face": FACE_PARAMS,
    "face2": FACE2_PARAMS,
    "face_scaled": SCALED_PARAMS,
}
#: Loss of the fit (squared; a soft-l1 loss at the force scale changed beta by < 10 % on the
#: two-stage test campaigns and read the first stage as outliers at smaller scales).
LOSS = "linear"
F_SCALE = 1.0
#: Faces whose recoil a :class:`Data` keeps, the least recently used dropped: a fit's point and
#: its finite differences, for each of two modes, and the start that the path's candidates
#: and the bootstrap's replicates share (40 recoils of 15,000 samples: 10 MB).
FACE_CACHE = 40
#: The library's Hertz exponent (``hertz_contact``).
HERTZ_EXPONENT = 1.5


@dataclass(frozen=True)
class Data:
    """Every recording's samples, concatenated (:func:`stack`)."""

    x: np.ndarray
    v: np.ndarray
    f: np.ndarray
    weight: np.ndarray
    rec: np.ndarray
    impact: np.ndarray  # campaign-wide impact number
    beta0: np.ndarray
    onset0: np.ndarray
    names: tuple[str, ...]
    #: Each recording's sampling interval in model time (the ``face`` term's filter).
    dt: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: Each sample's index in its record (empty: unknown; the face's ringing carried over).
    index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    #: The samples this is a subset of, and which: a face's ringing runs through all of them.
    parent: tuple[Data, np.ndarray] | None = None
    #: The beta at which a scaled face's mass is its ``face_mass`` (:func:`stack`'s).
    beta_ref: float = 30.0

    @property
    def n_rec(self) -> int:
        return len(self.names)

    @cached_property
    def layout(self) -> Layout:
        """The samples' impacts as padded arrays per recording (the ``face`` term's)."""
        return layout(self.rec, self.impact, self.n_rec)

    @cached_property
    def chain(self) -> ImpactChain | None:
        """The impacts' succession the face's ringing runs through (none without indices)."""
        if self.index.size != self.f.size or self.f.size == 0:
            return None
        return impact_chain(self.layout, self.index, self.dt)

    def behind_face(
        self, delta: np.ndarray, v: np.ndarray, params: dict[str, float], modes: Sequence[str]
    ) -> tuple[np.ndarray, np.ndarray]:
        """``delta`` and ``v`` less the recoil of each of the face's ``modes`` (``face``,
        ``face2``: :meth:`face_recoil` at that mode's ``params``)."""
        for mode in modes:
            y, yd = self.face_recoil(params[f"{mode}_mass"], params[f"{mode}_stiffness"],
                                     params[f"{mode}_damping"])  # fmt: skip
            delta, v = delta - y, v - yd
        return delta, v

    def face_recoil(
        self, mass: float | np.ndarray, stiffness: float | np.ndarray, damping: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """:func:`~.face.face_response` to the samples' force, the last faces' kept: it
        depends on the face alone, and a Jacobian's finite differences in the recordings'
        betas and onsets (half the residual evaluations of a fit) leave the face as it is.
        ``mass`` and ``stiffness`` may be each recording's (R,): a scaled face."""
        if self.parent is not None:  # the held-out impacts' force still drives the face
            full, idx = self.parent
            y, yd = full.face_recoil(mass, stiffness, damping)
            return y[idx], yd[idx]
        if np.ndim(mass) > 0:
            mass, stiffness = np.asarray(mass, float), np.asarray(stiffness, float)
            key: tuple = (mass.tobytes(), stiffness.tobytes(), float(damping))
        else:
            mass, stiffness = float(mass), float(stiffness)
            key = (mass, stiffness, float(damping))
        cache = self._face_cache
        if key in cache:  # the least recently used face goes first
            cache[key] = cache.pop(key)
        else:
            if len(cache) >= FACE_CACHE:
                cache.pop(next(iter(cache)))
            cache[key] = face_response(self.f, self.layout, self.dt, mass, stiffness,
                                       float(damping), chain=self.chain,
                                       drive=self._face_drive)  # fmt: skip
        return cache[key]

    @cached_property
    def _face_drive(self) -> tuple[np.ndarray, np.ndarray]:
        return force_drive(self.f, self.layout, self.dt)

    @cached_property
    def _face_cache(self) -> dict[tuple[float, float, float], tuple[np.ndarray, np.ndarray]]:
        return {}

    def weighted(self, weight: np.ndarray) -> Data:
        """The same samples with other weights (a bootstrap draw, a reweighting).

        The face's recoils are driven by the force, not the weights, so the copy shares
        this one's kept recoils and layout: every bootstrap replicate starts from the
        selected law's face and would otherwise filter the force again for it.
        """
        out = Data(self.x, self.v, self.f, weight, self.rec, self.impact, self.beta0,
                   self.onset0, self.names, self.dt, self.index, self.parent,
                   self.beta_ref)  # fmt: skip
        out.__dict__["_face_cache"] = self._face_cache  # cached_property's own slot
        out.__dict__["layout"] = self.layout
        out.__dict__["chain"] = self.chain
        out.__dict__["_face_drive"] = self._face_drive
        return out


def stack(samples: Sequence[ContactSamples]) -> Data:
    """Concatenate recordings' samples; weights make every recording's force scale 1."""
    xs, vs, fs, ws, rs, imps = [], [], [], [], [], []
    offset = 0
    for i, s in enumerate(samples):
        scale = max(float(np.std(s.force)), 1e-300)
        xs.append(s.displacement)
        vs.append(s.velocity)
        fs.append(s.force)
        ws.append(np.full(s.force.size, 1.0 / scale))
        rs.append(np.full(s.force.size, i))
        imps.append(s.impact + offset)
        offset += s.n_impacts
    cat = np.concatenate
    beta0 = np.array([max(s.beta, 1e-3) for s in samples])
    return Data(
        cat(xs), cat(vs), cat(fs), cat(ws), cat(rs), cat(imps),
        beta0, np.array([s.onset for s in samples]),
        tuple(s.recording for s in samples),
        np.array([sample_interval(s.displacement, s.velocity, s.impact) for s in samples]),
        cat([s.index for s in samples]) if all(s.index is not None for s in samples)
        else np.zeros(0, dtype=int), beta_ref=reference_beta(beta0),
    )  # fmt: skip


def recordings_subset(data: Data, keep: np.ndarray) -> Data:
    """The samples of the recordings ``keep`` (whole recordings, renumbered ``0..K-1``), as a
    campaign of their own: each keeps its weights, impacts and indices, so a face's ringing
    runs through the same samples it does in ``data``."""
    keep = np.unique(np.asarray(keep, dtype=int))
    new_of = np.full(data.n_rec, -1)
    new_of[keep] = np.arange(keep.size)
    sel = new_of[data.rec] >= 0
    return Data(
        data.x[sel], data.v[sel], data.f[sel], data.weight[sel], new_of[data.rec[sel]],
        data.impact[sel], data.beta0[keep], data.onset0[keep],
        tuple(data.names[i] for i in keep),
        data.dt[keep] if data.dt.size else data.dt,
        data.index[sel] if data.index.size == data.f.size else data.index,
        beta_ref=data.beta_ref,
    )  # fmt: skip


def shared_names(terms: frozenset[str]) -> list[str]:
    """The shared parameters of a set of terms, in a fixed order."""
    return [p[0] for t in TERMS if t in terms for p in TERM_PARAMS[t]]


def law_params(
    terms: frozenset[str], shared: dict[str, float], dr: float, beta_ref: float = 30.0
) -> dict[str, float]:
    """The ``learned_contact`` parameters of a law (neutral where a term is absent);
    ``beta_ref``: a scaled face's reference beta."""
    p = {**NEUTRAL, "reference_penetration": dr, "knee": 0.0}
    if "hertz" in terms:
        p["exponent"] = HERTZ_EXPONENT
    if "face_scaled" in terms:
        p["face_reference_beta"] = float(beta_ref)
    p.update({k: float(v) for k, v in shared.items()})
    return p


@dataclass
class Fit:
    """A law fitted to (part of) the samples."""

    terms: frozenset[str]
    theta: np.ndarray
    dr: float
    n_rec: int
    sse: float
    n: int
    #: A scaled face's reference beta (the samples', :attr:`Data.beta_ref`).
    beta_ref: float = 30.0

    @property
    def shared(self) -> dict[str, float]:
        names = shared_names(self.terms)
        return dict(zip(names, self.theta[2 * self.n_rec :].tolist(), strict=True))

    @property
    def betas(self) -> np.ndarray:
        return np.exp(self.theta[: self.n_rec])

    @property
    def onsets(self) -> np.ndarray:
        return self.theta[self.n_rec : 2 * self.n_rec]

    @property
    def params(self) -> dict[str, float]:
        return law_params(self.terms, self.shared, self.dr, self.beta_ref)

    @property
    def n_params(self) -> int:
        return self.theta.size


def predict(data: Data, terms: frozenset[str], theta: np.ndarray, dr: float) -> np.ndarray:
    """The law's contact force on every sample."""
    r = data.n_rec
    beta = np.exp(theta[:r])[data.rec]
    delta = data.x - theta[r : 2 * r][data.rec]
    shared = dict(zip(shared_names(terms), theta[2 * r :], strict=True))
    v = data.v
    # the law acts on the face, which recoils under the measured force (a second mode
    # recoils under the same force, in parallel at the tip)
    delta, v = data.behind_face(delta, v, shared, [m for m in FACE_MODES if m in terms])
    if "face_scaled" in terms:  # each recording's own face; the contact in front, stiffer
        y, yd = scaled_face_recoil(data, np.exp(theta[:r]), shared, data.beta_ref)
        delta, v = delta - y, v - yd
        ratio = shared["face_stiffness_ratio"]
        beta = beta * ratio / (ratio - 1.0)
    return learned_contact_force(delta, v, beta, law_params(terms, shared, dr))


def weighted_sse(data: Data, fit: Fit, mask: np.ndarray | None = None) -> float:
    """Weighted squared residual of a fitted law on the samples of ``mask`` (all by default)."""
    res = (predict(data, fit.terms, fit.theta, fit.dr) - data.f) * data.weight
    return float(np.sum(res[mask] ** 2) if mask is not None else np.sum(res**2))


def fit_law(
    data: Data,
    terms: frozenset[str],
    dr: float,
    start: dict[str, float] | None = None,
    per_rec: np.ndarray | None = None,
    mask: np.ndarray | None = None,
    max_nfev: int = 200,
    ftol: float = 1e-8,
) -> Fit:
    """Bounded least squares of a law with the given terms on the samples of ``mask``.

    Parameters
    ----------
    data : Data
    terms : frozenset of str
        Terms beyond the linear spring (:data:`TERMS`, or ``"hertz"``).
    dr : float
        Reference penetration of the power law.
    start : dict, optional
        Starting values of shared parameters (defaults from :data:`TERM_PARAMS`).
    per_rec : numpy.ndarray, optional
        Starting ``(log beta_r, e_r)`` (2R,); the restoring-force law's by default.
    mask : numpy.ndarray, optional
        Samples fitted (all by default): the training impacts of a fold.
    max_nfev : int
        Bound on residual evaluations.
    ftol : float
        Relative change of the cost that stops the fit (scipy's default, 1e-8).
    """
    r = data.n_rec
    names = shared_names(terms)
    bounds = {p[0]: (p[1], p[2]) for t in TERMS for p in TERM_PARAMS[t]}
    init = {p[0]: p[3] for t in TERMS for p in TERM_PARAMS[t]}
    init.update(start or {})
    if per_rec is None:
        per_rec = np.concatenate([np.log(data.beta0), data.onset0])
    lo = np.concatenate([np.full(r, -7.0), np.full(r, -np.inf), [bounds[n][0] for n in names]])
    hi = np.concatenate([np.full(r, 9.0), np.full(r, np.inf), [bounds[n][1] for n in names]])
    theta0 = np.clip(np.concatenate([per_rec, [init[n] for n in names]]), lo + 1e-9, hi - 1e-9)
    idx = np.arange(data.f.size) if mask is None else np.flatnonzero(mask)
    sub = _subset(data, idx)
    last: list[np.ndarray] = [np.full(theta0.size, np.nan), np.zeros(0)]

    def resid(th: np.ndarray) -> np.ndarray:
        out = (predict(sub, terms, th, dr) - sub.f) * sub.weight
        last[:] = [th.copy(), out]  # the Jacobian is asked for where the last step was taken
        return out

    def jac(th: np.ndarray) -> sparse.csr_matrix:
        f0 = last[1] if np.array_equal(th, last[0]) else resid(th)
        return difference_jacobian(resid, th, f0, sub.rec, r, (lo, hi))

    sol = optimize.least_squares(
        resid, theta0, bounds=(lo, hi), jac=jac, x_scale="jac", max_nfev=max_nfev,
        tr_solver="lsmr", loss=LOSS, f_scale=F_SCALE, ftol=ftol,
    )  # fmt: skip
    return Fit(terms, sol.x, dr, r, float(np.sum(sol.fun**2)), int(idx.size), data.beta_ref)


def difference_jacobian(
    resid: Callable[[np.ndarray], np.ndarray],
    theta: np.ndarray,
    f0: np.ndarray,
    rec: np.ndarray,
    n_rec: int,
    bounds: tuple[np.ndarray, np.ndarray],
) -> sparse.csr_matrix:
    """The residuals' forward-difference Jacobian at ``theta`` (M, 2R + S), sparse.

    Each sample's residual depends on its own recording's ``log beta`` and onset and on the
    shared parameters, so all betas are stepped in one evaluation, all onsets in another and
    each shared parameter in its own: scipy's ``least_squares`` does the same from a
    ``jac_sparsity`` pattern, with the same steps (``sqrt(eps) max(1, |theta|)``, reversed
    where a bound is in the way) and so the same matrix, but spends as long again as the
    evaluations on finding and assembling the pattern's entries at every Jacobian.
    """
    lo, hi = bounds
    h = np.sqrt(np.finfo(float).eps) * np.where(theta >= 0, 1.0, -1.0)
    h = h * np.maximum(1.0, np.abs(theta))
    h = step_within_bounds(theta, h, lo, hi)
    r, m, n = n_rec, f0.size, theta.size
    groups = [np.arange(r), np.arange(r, 2 * r), *([j] for j in range(2 * r, n))]
    vals = np.empty((m, len(groups)))
    for g, cols in enumerate(groups):
        x = theta.copy()
        x[cols] += h[cols]
        dx = x - theta
        # a per-recording group's column on each sample is its own recording's
        vals[:, g] = (resid(x) - f0) / (dx[cols[rec]] if g < 2 else dx[cols[0]])
    cols_of_row = np.empty((m, len(groups)), dtype=np.int32)
    cols_of_row[:, 0], cols_of_row[:, 1] = rec, r + rec
    cols_of_row[:, 2:] = np.arange(2 * r, n)
    indptr = np.arange(0, m * len(groups) + 1, len(groups), dtype=np.int32)
    return sparse.csr_matrix((vals.ravel(), cols_of_row.ravel(), indptr), shape=(m, n))


def step_within_bounds(
    theta: np.ndarray, h: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """Forward steps ``h`` turned back where ``theta + h`` leaves the bounds and the step fits
    the other way, else shortened to the wider side's room (scipy's one-sided rule)."""
    room_lo, room_hi = theta - lo, hi - theta
    x = theta + h
    out = h.copy()
    fits = np.abs(h) <= np.maximum(room_lo, room_hi)
    out[((x < lo) | (x > hi)) & fits] *= -1
    up = (room_hi >= room_lo) & ~fits
    out[up] = room_hi[up]
    down = (room_hi < room_lo) & ~fits
    out[down] = -room_lo[down]
    return out


def _subset(data: Data, idx: np.ndarray) -> Data:
    return Data(
        data.x[idx], data.v[idx], data.f[idx], data.weight[idx], data.rec[idx],
        data.impact[idx], data.beta0, data.onset0, data.names, data.dt,
        parent=(data, idx), beta_ref=data.beta_ref,
    )  # fmt: skip


def explained_fraction(data: Data, fit: Fit) -> float:
    """Fraction of the contact force's (weighted) variance the law explains, per recording
    centred: ``1 - SSE / sum_r sum_i w (F - mean_r F)**2``."""
    total = 0.0
    for r in range(data.n_rec):
        sel = data.rec == r
        total += float(np.sum(((data.f[sel] - data.f[sel].mean()) * data.weight[sel]) ** 2))
    return 1.0 - weighted_sse(data, fit) / max(total, 1e-300)
