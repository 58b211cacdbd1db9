r"""Beta in a learned Hunt-Crossley law's sense: the elastic slope at first contact.

A model trained with a learned contact law whose dissipation grows with penetration (the
``learned_contact`` effect with a ``hunt_crossley`` term, its card's ``data.priors``) labels
its recordings with that law's beta, the elastic slope at first contact (docs/crosscheck.md,
"beta for a nonlinear law")::

    F_c = max(0, K (d + a d v) + c_c v),   d = x - e > 0,   else 0

with ``beta = K / k``: at first touch (``d = 0``) the dissipation ``K a d v`` is nil and the
slope is ``K``. The library's law (:mod:`.contact_law`) has only the Kelvin-Voigt damper
``c_c v``; fitted to such a contact it moves its onset late (the force starts at zero at
first touch and rises slowly while the damper's would jump) and reads a steeper spring:
5-65 % high on the independent rig's Hunt-Crossley campaign.

The coefficient ``a`` is fitted free on every record, not held at the model's: it carries
the units of an inverse velocity, and the map's velocity is in the record's units, whose
gain the predictor does not know (its features are gain-invariant). Given the onset the law
is linear in ``K``, ``K a`` and ``c_c``, so the free term costs one column of the regression;
the onset is profiled over a grid first (:func:`hunt_crossley_start`), then refined with the
rest by least squares. On a contact without such dissipation ``a`` comes out near 0 and the
law is the library's linear one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg, optimize

from stiffnet.restoring_force.contact_law import ContactLaw, force_unit

#: Onsets profiled for the start, as quantiles of the displacements near impacts (as
#: :func:`~.contact_law.profile_contact_start`'s).
ONSET_QUANTILES = np.linspace(0.3, 0.98, 24)
#: Bound on the least-squares evaluations.
MAX_NFEV = 200


@dataclass(frozen=True)
class HuntCrossleyLaw:
    """A Hunt-Crossley law fitted on the map (:func:`fit_hunt_crossley_law`), map units.

    Attributes
    ----------
    stiffness : float
        ``K``: the elastic slope at first contact (``beta = K / k``).
    onset, damping : float
        ``e`` and the Kelvin-Voigt ``c_c``.
    dissipation : float
        ``a``: the dissipation per unit elastic force and velocity (``K a d v``), in the
        map's inverse velocity.
    dissipation_share : float
        The ``d v`` term's share of the dissipation at the reference penetration
        ``d_r``, ``K a d_r / (c_c + K a d_r)`` (0: a Kelvin-Voigt contact).
    r2, sse : float
        Fraction of the contact force's variance explained, residual sum of squares.
    n_samples : int
    """

    stiffness: float
    onset: float
    damping: float
    dissipation: float
    dissipation_share: float
    r2: float
    sse: float
    n_samples: int


def hunt_crossley_force(
    disp: np.ndarray,
    vel: np.ndarray,
    stiffness: float,
    onset: float,
    damping: float,
    dissipation: float,
) -> np.ndarray:
    """``max(0, K (d + a d v) + c_c v)`` where ``d = x - e > 0``, else 0."""
    d = np.maximum(np.asarray(disp) - onset, 0.0)
    v = np.asarray(vel)
    force = stiffness * d * (1.0 + dissipation * v) + damping * v
    return np.where(d > 0, np.maximum(force, 0.0), 0.0)


def hunt_crossley_shape(disp: np.ndarray, vel: np.ndarray, onset: float, dissipation: float):
    """The law's force per unit ``K`` less the damper's, ``d (1 + a v)`` (0 outside)."""
    d = np.maximum(np.asarray(disp) - onset, 0.0)
    return d * (1.0 + dissipation * np.asarray(vel))


def hunt_crossley_start(
    force: np.ndarray, disp: np.ndarray, vel: np.ndarray
) -> tuple[float, float, float, float] | None:
    """Starting ``(K, e, c_c, K a)`` by profiling the onset: for each onset of the grid the
    linear law ``F = K d + h d v + c_c v`` on the samples beyond it, scored clipped on all;
    None where no onset gives a positive ``K``."""
    best, best_sse = None, np.inf
    for e in np.quantile(disp, ONSET_QUANTILES):
        on = disp > e
        if on.sum() < 4:
            continue
        d = disp[on] - e
        a = np.column_stack([d, d * vel[on], vel[on]])
        k, h, c = linalg.lstsq(a, force[on])[0]
        if not k > 0:
            continue
        h, c = max(float(h), 0.0), max(float(c), 0.0)
        sse = float(np.sum((hunt_crossley_force(disp, vel, k, e, c, h / k) - force) ** 2))
        if sse < best_sse:
            best, best_sse = (float(k), float(e), c, h), sse
    return best


def fit_hunt_crossley_law(
    force: np.ndarray,
    disp: np.ndarray,
    vel: np.ndarray,
    near: np.ndarray,
    start: ContactLaw,
) -> HuntCrossleyLaw:
    """Least-squares Hunt-Crossley law with its ``d v`` term free.

    Parameters
    ----------
    force, disp, vel : numpy.ndarray
        Residual force and reconstructed state of the map.
    near : numpy.ndarray
        Boolean mask of the samples fitted (in contact and a margin around).
    start : ContactLaw
        The library's law on the same samples: one start (with ``a = 0``), beside the
        profiled one (:func:`hunt_crossley_start`).

    Returns
    -------
    HuntCrossleyLaw
        The better of the fits from both starts.
    """
    # in the force's own unit (force, penetration and velocity scale together: K and c_c do
    # not, the onset scales with them and h = K a inversely)
    unit = force_unit(force[near])
    f, x, v = force[near] / unit, disp[near] / unit, vel[near] / unit

    def residual(t: np.ndarray) -> np.ndarray:
        k = np.exp(t[0])
        return hunt_crossley_force(x, v, k, t[1], t[2], t[3] / k) - f

    lo, hi = [-np.inf, -np.inf, 0.0, 0.0], [np.inf] * 4
    starts = [(start.stiffness, start.onset / unit, start.damping, 0.0)]
    profiled = hunt_crossley_start(f, x, v)
    if profiled is not None:
        starts.append(profiled)
    best = None
    for k0, e0, c0, h0 in starts:
        theta0 = np.clip([np.log(k0), e0, max(c0, 0.0), max(h0, 0.0)], lo, hi)
        sol = optimize.least_squares(residual, theta0, bounds=(lo, hi), x_scale="jac",
                                     max_nfev=MAX_NFEV)  # fmt: skip
        if best is None or sol.cost < best.cost:
            best = sol
    k, c = float(np.exp(best.x[0])), float(best.x[2])
    e, h = float(best.x[1]) * unit, float(best.x[3]) / unit
    sse = float(np.sum(best.fun**2)) * unit**2
    tss = max(float(np.sum((f - f.mean()) ** 2)) * unit**2, 1e-300)
    dr = start.reference_penetration
    share = h * dr / (c + h * dr) if c + h * dr > 0 else 0.0
    return HuntCrossleyLaw(k, e, c, h / k, float(share), 1.0 - sse / tss, sse, int(f.size))
