r"""The contact law's exponent read with an onset per impact.

The reconstructed displacement (:mod:`~stiffnet.restoring_force.free_flight`) can carry a
level that differs from one impact to the next. On shallow contacts that is of the order of
the penetration: on ``bench_alarm``'s power-law draw 9 (offset 0, exponent 2.01) the eleven
impacts all peak at the same force (within 3 %) while their mapped peak displacements spread
over about the penetration (docs/measurement_loop.md). The map's impacts are then shifted
copies of the law, and one shared onset smears a convex law into a straight line: that draw,
read with one onset, fits best at an exponent below 1, at R\ :sup:`2` 0.83.

Here each impact gets its own onset (the nuisance the reconstruction leaves), sharing the
law's stiffness, damping and exponent (:func:`~.contact_law.contact_force`'s law)::

    F_c = max(0, K d_r (d_j / d_r)**p + c_c v),   d_j = x - e_j > 0,   else 0

fitted on the samples near impacts, from exponents spread over the fit's bounds
(:data:`EXPONENT_STARTS`: with the onsets free, a start at the bound stays there on a map
whose shape first needs the onsets to move). The same power-law draw then reads p 1.89 at
R\ :sup:`2` 0.96 (drawn 2.01). Linear contacts keep p near 1: the exponent still has to
bend every impact the same way.

The reading only reports (:class:`ImpactOnsetLaw`): beta and its interval stay the shared
onset law's, and the alarm's exponent rules read it where the shared law's exponent does not
count (:func:`stiffnet.uncertainty.unseen_law.exponent_reading`). The same law is refitted
with Hunt-Crossley's dissipation on its elastic force, ``(1 + a v)``, from that end point:
its R\ :sup:`2` and the term's share of the dissipation are reported beside (the term the
library's Kelvin-Voigt law lacks, read on a map freed of the wandering level).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage, optimize

from stiffnet.restoring_force.contact_law import EXPONENT_BOUNDS, ContactLaw, force_unit

#: Exponents the fit starts from (the best end point wins), inside :data:`EXPONENT_BOUNDS`.
EXPONENT_STARTS = (1.0, 1.5, 2.0, 2.5)
#: Least impacts, and least samples in contact per impact, for an onset per impact: with
#: fewer the onsets absorb the law's shape.
MIN_IMPACTS = 4
MIN_CONTACT_SAMPLES = 3
#: Bound on the least-squares evaluations of one start.
MAX_NFEV = 400


@dataclass(frozen=True)
class ImpactOnsetLaw:
    """The contact law fitted with an onset per impact (:func:`fit_impact_onset_law`).

    Attributes
    ----------
    exponent : float
        ``p`` read with an onset per impact.
    r2 : float
        Fraction of the contact force's variance explained on the samples fitted.
    onset_spread : float
        Standard deviation of the impacts' onsets over the reference penetration ``d_r``:
        how far the reconstruction's level wanders between impacts.
    n_impacts : int
        Impacts fitted.
    linear_r2 : float
        R2 of the linear law (``p = 1``) with the same onsets free (at most :attr:`r2`).
    dissipation_r2 : float
        R2 of the same law with Hunt-Crossley's dissipation ``(1 + a v)`` on its elastic force
        (one more parameter, shared by the impacts).
    dissipation_share : float
        That term's share of the dissipation at the reference penetration,
        ``K a d_r / (|c_c| + |K a d_r|)``, signed (positive: a dissipation growing with
        the penetration).
    """

    exponent: float
    r2: float
    onset_spread: float
    n_impacts: int
    linear_r2: float = float("nan")
    dissipation_r2: float = float("nan")
    dissipation_share: float = float("nan")

    def to_dict(self) -> dict[str, float | int]:
        """JSON-ready fields."""
        return {
            "exponent": float(self.exponent),
            "r2": float(self.r2),
            "onset_spread": float(self.onset_spread),
            "n_impacts": int(self.n_impacts),
            "linear_r2": float(self.linear_r2),
            "dissipation_r2": float(self.dissipation_r2),
            "dissipation_share": float(self.dissipation_share),
        }


def fit_impact_onset_law(
    force: np.ndarray,
    disp: np.ndarray,
    vel: np.ndarray,
    labels: np.ndarray,
    core: np.ndarray,
    law: ContactLaw,
) -> ImpactOnsetLaw | None:
    """The contact law with an onset per impact (see the module notes).

    Parameters
    ----------
    force, disp, vel : numpy.ndarray
        The map: residual force and reconstructed state (the record's gain).
    labels : numpy.ndarray
        Impact label of every sample (0: free flight), the margins around contacts included.
    core : numpy.ndarray
        Boolean mask of the samples in contact.
    law : ContactLaw
        The law fitted with one onset: its onset, stiffness, damping and reference
        penetration start the fit.

    Returns
    -------
    ImpactOnsetLaw or None
        None where fewer than :data:`MIN_IMPACTS` impacts hold
        :data:`MIN_CONTACT_SAMPLES` samples in contact.
    """
    n_labels = int(labels.max()) if labels.size else 0
    sizes = np.asarray(ndimage.sum(core, labels, np.arange(1, n_labels + 1)))
    kept = np.flatnonzero(sizes >= MIN_CONTACT_SAMPLES) + 1
    if kept.size < MIN_IMPACTS:
        return None
    near = np.isin(labels, kept)
    impact = np.searchsorted(kept, labels[near])
    unit = force_unit(force[near])
    f, x, v = force[near] / unit, disp[near] / unit, vel[near] / unit
    dr = law.reference_penetration / unit
    # each impact's onset starts where its own first contact sample lies, less the shared
    # law's step from its onset to the first sample
    first = np.asarray(
        ndimage.minimum(np.where(core[near], x, np.inf), impact, np.arange(kept.size))
    )
    lead = float(np.median(first)) - law.onset / unit
    onsets0 = first - lead

    def resid(theta: np.ndarray) -> np.ndarray:
        k, c, p = np.exp(theta[0]), theta[1], theta[2]
        dissipation = theta[3] if theta.size > kept.size + 3 else 0.0
        onset = theta[-kept.size :][impact]
        with np.errstate(over="ignore", invalid="ignore"):
            d = np.maximum(x - onset, 0.0)
            elastic = k * dr * (d / dr) ** p
            out = np.where(d > 0, np.maximum(elastic * (1 + dissipation * v) + c * v, 0.0), 0.0)
        return out - f

    lo = np.r_[-np.inf, 0.0, EXPONENT_BOUNDS[0], np.full(kept.size, -np.inf)]
    hi = np.r_[np.inf, np.inf, EXPONENT_BOUNDS[1], np.full(kept.size, np.inf)]
    best = None
    for p0 in EXPONENT_STARTS:
        theta0 = np.r_[np.log(law.stiffness), max(law.damping, 0.0), p0, onsets0]
        sol = optimize.least_squares(
            resid, np.clip(theta0, lo, hi), bounds=(lo, hi), x_scale="jac", max_nfev=MAX_NFEV
        )
        if best is None or sol.cost < best.cost:
            best = sol
    # the linear law with the same onsets free: what the exponent adds to it
    linear = optimize.least_squares(
        lambda t: resid(np.r_[t[:2], 1.0, t[2:]]),
        np.r_[np.log(law.stiffness), max(law.damping, 0.0), onsets0],
        bounds=(np.r_[lo[:2], lo[3:]], np.r_[hi[:2], hi[3:]]), x_scale="jac", max_nfev=MAX_NFEV,
    )  # fmt: skip
    # the same law with Hunt-Crossley's dissipation on the elastic force, from its end point
    theta0 = np.r_[best.x[:3], 0.0, best.x[3:]]
    wide = optimize.least_squares(
        resid, theta0, bounds=(np.r_[lo[:3], -np.inf, lo[3:]], np.r_[hi[:3], np.inf, hi[3:]]),
        x_scale="jac", max_nfev=MAX_NFEV,
    )  # fmt: skip
    if wide.cost > best.cost:  # a stalled fit: the term explains nothing
        wide.x, wide.cost = theta0, best.cost
    total = max(float(np.sum((f - f.mean()) ** 2)), 1e-300)
    k, c, a = float(np.exp(wide.x[0])), float(wide.x[1]), float(wide.x[3])
    hc = k * a * dr  # the term's damping at the reference penetration
    return ImpactOnsetLaw(
        exponent=float(best.x[2]),
        r2=1.0 - 2.0 * float(best.cost) / total,
        linear_r2=1.0 - 2.0 * float(max(linear.cost, best.cost)) / total,
        onset_spread=float(np.std(best.x[3:]) / dr) if dr > 0 else float("nan"),
        n_impacts=int(kept.size),
        dissipation_r2=1.0 - 2.0 * float(wide.cost) / total,
        dissipation_share=hc / (abs(c) + abs(hc)) if abs(c) + abs(hc) > 0 else 0.0,
    )
