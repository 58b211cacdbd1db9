r"""The contact's own oscillation, read from the samples in contact: beta without integrating.

In contact the restraint and the primary spring act in parallel on the mass
(eq. 12 with ``H = 1``; a Kelvin-Voigt restraint, ``contact_damping``)::

    d'' + (c + c_c) d' + (k + K) d = f(tau)        (d: penetration, f: slow forcing)

so the contact force ``F = K d + c_c d'`` is a damped oscillation at the poles
``s = -sigma +- i omega_d`` (``omega_d**2 + sigma**2 = k + K``, ``2 sigma = c + c_c``)
plus a part that follows the slow forcing, nearly constant over one contact.
Sampled every ``Delta``, any such oscillation obeys the exact recursion::

    F[n+1] = a1 F[n] + a2 F[n-1] + b,   a1 = 2 r cos(omega_d Delta),  a2 = -r**2,
                                        r = exp(-sigma Delta)

(the discrete poles ``z = exp(s Delta)``; Ljung, *System Identification*, the
step-invariant model of a second-order system). A least-squares fit of ``a1``,
``a2`` on the samples strictly inside the contacts gives ``k + K`` and so
``beta = (omega_d**2 + sigma**2) / k - 1`` with no displacement at all: neither
the onset, which falls between samples (a damped contact's force jumps there,
and the integral of that jump is what the force-displacement map gets wrong
with a few samples per contact), nor the table's motion enters. It needs three
samples in a row in contact; the constant ``b`` is one per impact where each
impact gives two equations or more, else shared (the impacts of a steady orbit
are alike).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg, ndimage


@dataclass(frozen=True)
class ContactPoles:
    """Contact oscillation from the recursion of the in-contact samples (:func:`fit_contact_poles`).

    Attributes
    ----------
    total_stiffness : float
        ``k + K = omega_d**2 + sigma**2`` (time in the record's units).
    decay : float
        ``sigma = (c + c_c) / 2``.
    log_se : float
        Standard error of ``log(k + K)`` (delta method on the least squares).
    r2 : float
        Fraction of the in-contact samples' variance the recursion explains.
    n_equations : int
    """

    total_stiffness: float
    decay: float
    log_se: float
    r2: float
    n_equations: int


def _poles(a1: float, a2: float, dt: float) -> tuple[float, float] | None:
    """``(omega_d**2 + sigma**2, sigma)`` of the recursion's complex pole pair, else None."""
    if not a2 < 0:
        return None
    r = float(np.sqrt(-a2))
    cos_t = a1 / (2 * r)
    if not -1 < cos_t < 1:
        return None  # real poles: not an oscillation
    sigma = -np.log(r) / dt
    omega = float(np.arccos(cos_t)) / dt
    return omega**2 + sigma**2, sigma


def fit_contact_poles(force: np.ndarray, contact: np.ndarray, dt: float) -> ContactPoles | None:
    """Fit the recursion on the runs of `contact` samples; None without enough of them.

    Parameters
    ----------
    force : numpy.ndarray
        Contact force (the free-flight law's residual), any gain.
    contact : numpy.ndarray
        Boolean mask of samples in contact (clearly above the free-flight scatter).
    dt : float
        Sampling interval in the units of the stiffness wanted.
    """
    labels, n = ndimage.label(contact)
    rows: list[int] = []
    group: list[int] = []
    for j, sl in enumerate(ndimage.find_objects(labels), start=1):
        idx = np.arange(sl[0].start, sl[0].stop)[labels[sl] == j]
        rows += list(idx[1:-1])
        group += [j] * max(idx.size - 2, 0)
    t = np.asarray(rows, dtype=int)
    if t.size < 6:
        return None
    g = np.asarray(group)
    ids, counts = np.unique(g, return_counts=True)
    per_impact = bool(np.median(counts) >= 2)
    cols = [force[t], force[t - 1]]
    if per_impact:
        cols += [(g == i).astype(float) for i in ids]
    else:
        cols.append(np.ones(t.size))
    x = np.column_stack(cols)
    y = force[t + 1]
    dof = t.size - x.shape[1]
    if dof < 2:
        return None
    coef, *_ = linalg.lstsq(x, y)
    poles = _poles(float(coef[0]), float(coef[1]), dt)
    if poles is None:
        return None
    resid = y - x @ coef
    r2 = 1.0 - float(resid @ resid) / max(float(np.sum((y - y.mean()) ** 2)), 1e-300)
    # delta method: the gradient of log(k + K) in (a1, a2), numerically
    try:
        cov = float(resid @ resid) / dof * linalg.inv(x.T @ x)[:2, :2]
    except linalg.LinAlgError:
        return None
    grad = np.zeros(2)
    for i in range(2):
        step = np.zeros(2)
        step[i] = 1e-6 * max(abs(coef[i]), 1e-3)
        hi = _poles(*(coef[:2] + step), dt)
        lo = _poles(*(coef[:2] - step), dt)
        if hi is None or lo is None:
            return None
        grad[i] = (np.log(hi[0]) - np.log(lo[0])) / (2 * step[i])
    log_se = float(np.sqrt(max(grad @ cov @ grad, 0.0)))
    return ContactPoles(poles[0], poles[1], log_se, r2, int(t.size))
