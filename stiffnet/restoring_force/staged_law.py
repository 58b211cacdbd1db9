r"""Beta in a two-stage learned law's sense: the first-stage slope of the force-displacement map.

A model trained with a learned contact law (the ``learned_contact`` effect with a second
stage, its card's ``data.priors``) labels its recordings with that law's beta, the elastic
slope at first contact (docs/crosscheck.md, "beta for a nonlinear law")::

    F_c = max(0, K (d + (r - 1) max(d - d_k, 0)) + c_c v),   d = x - e > 0,   else 0

with ``beta = K / k``. The library's law (:mod:`.contact_law`) fits one slope (or a power
law) across both stages, so on such a rig its beta is neither stage's: 0.6-2.4x the first
stage's on the independent rig's two-stage campaign. Here the law is fitted with the
stage ratio ``r`` held at the model's (dimensionless, so it carries over from the model's
units to the record's) and the knee ``d_k`` free: the knee is a length, and the record's
gain, which would convert the card's knee into the map's units, is unknown to the
predictor (its features are gain-invariant).

Where the map shows no knee (the stage does not earn its parameter over one slope,
:func:`stage_resolved`) the impacts are all in one stage and the map cannot say which:
beta is read as the one slope ``S`` (every impact short of the knee), and ``S / r`` (every
impact beyond it) is reported beside, not as beta (see
:func:`stiffnet.restoring_force.estimate._staged_beta` for why).

The ratio is held, not fitted: on a rig whose ratio is the model's that reads beta best,
and a rig with another ratio is outside the model's world. There the held ratio biases
beta: on the independent rig with ratio 3 under a card of 2.31-2.56, +7 to +25 % on 21 of
22 recordings (a free ratio read 13 of them within 7 %, but beat the held one significantly
on 5 only), so the cross-check then agrees with a model that reads high.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize, stats

from stiffnet.restoring_force.contact_law import ContactLaw, fit_contact_law, force_unit

#: Significance level of the knee over one slope (F-test, one parameter): as the exponent's.
STAGE_LEVEL = 1e-3
#: Knee starts, as quantiles of the penetrations in contact (the fit is not smooth in it).
KNEE_STARTS = (0.2, 0.4, 0.6, 0.8)
#: Bound on the least-squares evaluations per start.
MAX_NFEV = 200


@dataclass(frozen=True)
class StagedLaw:
    """A two-stage law fitted on the map (:func:`fit_staged_law`), in the map's units.

    Attributes
    ----------
    stiffness : float
        ``K``: the first-stage slope (``beta = K / k``); the one slope where the knee is
        not resolved.
    onset, damping : float
        ``e`` and ``c_c``.
    knee : float
        ``d_k``: penetration where the second stage begins (inf where not resolved).
    ratio : float
        ``r``: the stage ratio held (the model's).
    r2, sse : float
        Fraction of the contact force's variance explained, residual sum of squares.
    n_samples : int
    resolved : bool
        Whether the knee lies within the impacts (:func:`stage_resolved`).
    knee_fraction : float
        ``d_k`` over the median peak penetration of the impacts (nan where not resolved).
    """

    stiffness: float
    onset: float
    damping: float
    knee: float
    ratio: float
    r2: float
    sse: float
    n_samples: int
    resolved: bool
    knee_fraction: float = float("nan")


def staged_force(
    disp: np.ndarray,
    vel: np.ndarray,
    stiffness: float,
    onset: float,
    damping: float,
    knee: float,
    ratio: float,
) -> np.ndarray:
    """``max(0, K (d + (r - 1) max(d - d_k, 0)) + c_c v)`` where ``d = x - e > 0``, else 0."""
    elastic = stiffness * staged_shape(disp, onset, knee, ratio)
    inside = np.asarray(disp) - onset > 0
    return np.where(inside, np.maximum(elastic + damping * np.asarray(vel), 0.0), 0.0)


def staged_shape(disp: np.ndarray, onset: float, knee: float, ratio: float) -> np.ndarray:
    """The law's elastic shape per unit ``K``, ``d + (r - 1) max(d - d_k, 0)`` (0 outside)."""
    d = np.maximum(np.asarray(disp) - onset, 0.0)
    return d + (ratio - 1.0) * np.maximum(d - knee, 0.0)


def fit_staged_law(
    force: np.ndarray,
    disp: np.ndarray,
    vel: np.ndarray,
    near: np.ndarray,
    start: ContactLaw,
    ratio: float,
    peak_penetration: float,
) -> StagedLaw:
    """Least-squares two-stage law with the ratio held, against one slope.

    Parameters
    ----------
    force, disp, vel : numpy.ndarray
        Residual force and reconstructed state of the map.
    near : numpy.ndarray
        Boolean mask of the samples fitted (in contact and a margin around).
    start : ContactLaw
        The library's law on the same samples (:func:`~.contact_law.fit_contact_law`):
        the start of the onset, the slope and the damping.
    ratio : float
        The stage ratio ``r`` held (the model's learned law's ``knee_ratio``).
    peak_penetration : float
        Median peak penetration of the impacts (the knee is reported as a fraction of it).

    Returns
    -------
    StagedLaw
        The two-stage law where the knee is resolved, else the one-slope law.
    """
    f, x, v = force[near], disp[near], vel[near]
    linear = fit_contact_law(force, disp, vel, near,
                             (start.stiffness, start.onset, start.damping),
                             start.reference_penetration, exponent=1.0)  # fmt: skip
    tss = max(float(np.sum((f - f.mean()) ** 2)), 1e-300)
    best = _best_staged(f, x, v, linear, ratio)
    one = StagedLaw(linear.stiffness, linear.onset, linear.damping, np.inf, ratio,
                    linear.r2, linear.sse, int(f.size), resolved=False)  # fmt: skip
    if best is None:
        return one
    theta, sse = best
    if not stage_resolved(linear.sse, sse, f.size):
        return one
    knee = float(np.exp(theta[3]))
    fraction = knee / peak_penetration if peak_penetration > 0 else np.nan
    return StagedLaw(float(np.exp(theta[0])), float(theta[1]), float(theta[2]), knee, ratio,
                     1.0 - sse / tss, sse, int(f.size), resolved=True,
                     knee_fraction=fraction)  # fmt: skip


def _best_staged(
    f: np.ndarray, x: np.ndarray, v: np.ndarray, linear: ContactLaw, ratio: float
) -> tuple[np.ndarray, float] | None:
    """The best of the fits started from :data:`KNEE_STARTS`: ``(theta, sse)``, theta =
    ``(log K, e, c_c, log d_k)``; None where no sample is in contact."""
    pen = x - linear.onset
    inside = pen[pen > 0]
    if inside.size < 4:
        return None

    best: tuple[np.ndarray, float] | None = None
    for q in KNEE_STARTS:
        knee = float(np.quantile(inside, q))
        # below the knee the slope is K, beyond it r K: the one slope lies between
        k0 = linear.stiffness * 2.0 / (1.0 + ratio)
        theta0 = np.array([np.log(k0), linear.onset, max(linear.damping, 0.0), np.log(knee)])
        res = _least_squares(f, x, v, ratio, theta0)
        sse = float(np.sum(res.fun**2))
        if best is None or sse < best[1]:
            best = (res.x, sse)
    return best


def refit_at_ratio(
    law: StagedLaw, force: np.ndarray, disp: np.ndarray, vel: np.ndarray, near: np.ndarray,
    ratio: float,
) -> float:  # fmt: skip
    """The first-stage slope ``K`` of a resolved law refitted with another ratio held (the
    ends of the model's prior range: their readings join the interval)."""
    theta0 = np.array([np.log(law.stiffness), law.onset, law.damping, np.log(law.knee)])
    res = _least_squares(force[near], disp[near], vel[near], ratio, theta0)
    return float(np.exp(res.x[0]))


def _least_squares(
    f: np.ndarray, x: np.ndarray, v: np.ndarray, ratio: float, theta0: np.ndarray
) -> optimize.OptimizeResult:
    """The two-stage law with ``ratio`` held fitted from ``theta0`` = ``(log K, e, c_c,
    log d_k)`` (the damping non-negative)."""
    unit = force_unit(f)  # force, penetration and velocity scale together
    fu, xu, vu = f / unit, x / unit, v / unit
    # theta's onset and log knee are lengths; log K and c_c are ratios of scaled quantities
    to_unit = np.array([0.0, 0.0, 0.0, -np.log(unit)])

    def residual(t: np.ndarray) -> np.ndarray:
        return staged_force(xu, vu, np.exp(t[0]), t[1], t[2], np.exp(t[3]), ratio) - fu

    start = np.asarray(theta0, dtype=float) + to_unit
    start[1] /= unit
    lo, hi = [-np.inf, -np.inf, 0.0, -np.inf], [np.inf, np.inf, np.inf, np.inf]
    res = optimize.least_squares(residual, start, bounds=(lo, hi), x_scale="jac",
                                 max_nfev=MAX_NFEV)  # fmt: skip
    res.x = res.x - to_unit
    res.x[1] *= unit
    res.fun = res.fun * unit
    return res


def stage_resolved(sse_one: float, sse_staged: float, n: int, level: float = STAGE_LEVEL) -> bool:
    """Rule: the knee earns its parameter over one slope (F-test at `level`): the map shows
    both stages. A knee below the first samples, or beyond the deepest, leaves one slope."""
    dof = n - 4
    if dof < 1 or not sse_staged < sse_one:
        return False
    f_stat = (sse_one - sse_staged) / max(sse_staged / dof, 1e-300)
    return bool(f_stat > stats.f.ppf(1.0 - level, 1, dof))
