"""The free-flight law and the table's motion, fitted on the samples out of contact.

Out of contact the restoring force is linear (eq. 12 with ``H = 0``)::

    -y = c v + k x                      (y: acceleration, x, v: relative state)

and the reconstructed state is ``x = x_i + s(tau) + x_0``, ``v = v_i + s'(tau)``
(:mod:`~stiffnet.restoring_force.reconstruct`), with ``s`` the table's
displacement at the forcing harmonics. Substituting gives a regression that is
*linear* in every unknown::

    -y = c v_i + k x_i + sum_m (p_m cos m tau + q_m sin m tau) + d

from which ``s`` follows harmonic by harmonic (``k s + c s' = p cos + q sin``)
and ``x_0 = d / k``. A gain ``g`` on the record scales ``x_i``, ``v_i`` and
``y`` alike, so ``k`` and ``c`` do not depend on it.

Impacts are the samples where the residual force ``-y - (c v + k x)`` rises far
above the free-flight scatter: least squares on every sample starts the split,
then least squares on the free samples alone and a new split, a few times (the
contact forces are one-sided outliers, so a loose cut first removes them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg, ndimage

#: Forcing harmonics fitted for the table's motion (the shaker's 2nd and 3rd).
HARMONICS = (1, 2, 3)
#: A sample is in contact when its residual force exceeds this many robust sigmas.
CONTACT_SIGMAS = 5.0
#: In a chain's inverse, a run of at most this many free samples is no flight of its own (a
#: line fitted to so few samples is arbitrary, and the contact on either side blends into
#: it): a deconvolved pulse's ripple split off such runs and wrecked beta. Longer runs
#: (between a mount's ringing lobes) stay flights. A record as recorded has no such ripple,
#: and there the rule only moves the free damping (a mount's 0.031 read 0.028).
MIN_FLIGHT_SAMPLES = 3


@dataclass(frozen=True)
class FreeFlightFit:
    """Free-flight law, table motion and contact split (:func:`fit_free_flight`).

    Attributes
    ----------
    stiffness, damping : float
        ``k`` and ``c`` of ``-y = c v + k x`` (time in forcing radians, any gain).
    table : numpy.ndarray
        ``(len(harmonics), 2)`` cosine and sine amplitudes of the table's
        displacement ``s`` at each harmonic (the record's gain).
    offset : float
        ``x_0``: mean relative displacement.
    displacement, velocity : numpy.ndarray
        Reconstructed relative state ``x`` and ``v``.
    force : numpy.ndarray
        Residual (contact) force ``-y - (c v + k x)``.
    contact : numpy.ndarray
        Boolean mask of samples in contact.
    sigma : float
        Robust scatter of the residual force out of contact.
    r2 : float
        Fraction of the free-flight restoring force's variance explained.
    """

    stiffness: float
    damping: float
    table: np.ndarray
    offset: float
    displacement: np.ndarray
    velocity: np.ndarray
    force: np.ndarray
    contact: np.ndarray
    sigma: float
    r2: float


def free_flight_design(
    vel: np.ndarray, disp: np.ndarray, tau: np.ndarray, harmonics=HARMONICS
) -> np.ndarray:
    """Regressors ``[v_i, x_i, 1, cos m tau, sin m tau, ...]`` of the free-flight law."""
    cols = [vel, disp, np.ones_like(tau)]
    for m in harmonics:
        cols += [np.cos(m * tau), np.sin(m * tau)]
    return np.column_stack(cols)


def scaled_lstsq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least squares by the normal equations of the unit-norm columns (zero columns get 0).

    The designs are tall and narrow (thousands of rows, 9-40 columns) and, with
    their columns scaled, well conditioned, so a Cholesky solve of the Gram
    matrix costs a fraction of an SVD.
    """
    norms = np.sqrt(np.einsum("ij,ij->j", a, a))
    keep = norms > 0
    scaled = a[:, keep] / norms[keep]
    gram = scaled.T @ scaled
    gram[np.diag_indices_from(gram)] += 1e-12
    out = np.zeros(a.shape[1])
    try:
        out[keep] = linalg.cho_solve(linalg.cho_factor(gram), scaled.T @ b) / norms[keep]
    except (linalg.LinAlgError, ValueError):
        out[keep] = np.nan
    if not np.all(np.isfinite(out)):  # (nearly) singular: the SVD's minimum-norm answer
        out[keep] = linalg.lstsq(scaled, b)[0] / norms[keep]
    return out


def _impulse_corrections(
    accel: np.ndarray,
    vel: np.ndarray,
    disp: np.ndarray,
    tau: np.ndarray,
    use: np.ndarray,
    free: np.ndarray,
    contact: np.ndarray,
    stiffness: float,
    damping: float | None = None,
    min_flight: int = 0,
) -> tuple[np.ndarray, np.ndarray, float, float] | None:
    """Per-flight line corrections of the displacement: the impulses' quadrature errors.

    A spike sampled with a few points carries an impulse the discrete integral
    gets a few percent wrong, so the integrated velocity steps by a different
    error at every impact and the displacement drifts by a different ramp in
    every flight. With ``k`` known, each flight ``j`` (a run of more than
    `min_flight` free samples; shorter runs join the contact) gets its own line
    ``a_j + b_j tau``, fitted with the free-flight law (``-y - k x = c v + k
    (a_j + b_j tau) + c b_j``); inside a contact the correction passes from one
    flight's line to the next in proportion to the impulse received so far.

    Returns
    -------
    corr, dcorr : numpy.ndarray
        Displacement and velocity corrections.
    damping, r2 : float
        Refitted ``c`` and the free-flight goodness of fit.
    None
        With fewer than two flights (no contact): nothing to correct.
    """
    flights, n = ndimage.label(free)
    corr = np.zeros_like(tau)
    dcorr = np.zeros_like(tau)
    if n < 2:
        return None
    sizes = np.asarray(ndimage.sum(free, flights, np.arange(1, n + 1)))
    short = np.flatnonzero(sizes <= min_flight) + 1
    if short.size:  # too short for a line: part of the contact around it
        free = free & ~np.isin(flights, short)
        flights, n = ndimage.label(free)
        if n < 2:
            return None
    target = -accel - stiffness * disp
    idx = np.arange(1, n + 1)
    centre = ndimage.mean(tau, flights, idx)
    rows = np.flatnonzero(free)
    j = flights[rows] - 1
    a = np.zeros((rows.size, 1 + 2 * n))
    a[:, 0] = vel[rows]
    a[np.arange(rows.size), 1 + j] = 1.0
    a[np.arange(rows.size), 1 + n + j] = tau[rows] - centre[j]
    if damping is not None:
        target = target - damping * vel
        a[:, 0] = 0.0
    coef = scaled_lstsq(a, target[rows])
    c = float(coef[0]) if damping is None else float(damping)
    slope = coef[1 + n :] / stiffness
    level = (coef[1 : 1 + n] - c * slope) / stiffness
    r2 = 1.0 - float(np.var(target[rows] - a @ coef)) / max(float(np.var(-accel[rows])), 1e-300)

    def line(i: int | np.ndarray, t: np.ndarray) -> np.ndarray:
        return level[i] + slope[i] * (t - centre[i])

    on = flights > 0
    corr[on] = line(flights[on] - 1, tau[on])  # each flight on its own line
    dcorr[on] = slope[flights[on] - 1]
    # between flights: blend the neighbouring lines by the impulse received so far
    gaps, m = ndimage.label(~free)
    force = np.maximum(target - c * vel, 0.0)
    for span in ndimage.find_objects(gaps):  # a gap is one run of samples
        pos = np.arange(span[0].start, span[0].stop)
        before = flights[pos[0] - 1] - 1 if pos[0] > 0 else -1
        after = flights[pos[-1] + 1] - 1 if pos[-1] + 1 < tau.size else -1
        if before < 0 and after < 0:
            continue
        if before < 0 or after < 0:
            i = after if before < 0 else before
            corr[pos], dcorr[pos] = line(i, tau[pos]), slope[i]
            continue
        share = np.cumsum(force[pos])
        share = share / share[-1] if share[-1] > 0 else np.linspace(0, 1, pos.size)
        corr[pos] = (1 - share) * line(before, tau[pos]) + share * line(after, tau[pos])
        dcorr[pos] = (1 - share) * slope[before] + share * slope[after]
    return corr, dcorr, c, r2


def robust_split(
    design: np.ndarray, target: np.ndarray, use: np.ndarray, dilate: int = 2
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Least squares of a free-flight regression with the contacts split off as outliers.

    The contact forces are one-sided outliers: least squares on every sample,
    then on the samples whose residual stays within the free-flight scatter, a
    few times, the first passes with a looser cut (they are biased by the
    contacts).

    Returns
    -------
    coef : numpy.ndarray
        Coefficients on the free samples.
    free, contact : numpy.ndarray
        Boolean masks (contact dilated by `dilate` samples, both within `use`).
    sigma : float
        Robust scatter of the residual on the free samples.
    """
    scale = float(np.std(target)) or 1.0
    free = use.copy()
    contact = np.zeros_like(use)
    sigma = scale
    coef = scaled_lstsq(design[free], target[free])
    for i in range(5):
        force = target - design @ coef
        resid = force[free]
        sigma = 1.4826 * float(np.median(np.abs(resid - np.median(resid)))) or 1e-12 * scale
        contact = force > (CONTACT_SIGMAS if i >= 2 else 2.0) * sigma
        contact = ndimage.binary_dilation(contact, iterations=dilate) & use
        free = use & ~contact
        coef = scaled_lstsq(design[free], target[free])
    return coef, free, contact, sigma


def table_motion(coef: np.ndarray, stiffness: float, damping: float, harmonics=HARMONICS):
    """Solve ``k s + c s' = p cos + q sin`` for the table's ``(cos, sin)`` amplitudes."""
    out = np.empty((len(harmonics), 2))
    for i, m in enumerate(harmonics):
        a = np.array([[stiffness, damping * m], [-damping * m, stiffness]])
        out[i] = np.linalg.solve(a, coef[2 * i : 2 * i + 2])
    return out


def fit_free_flight(
    accel: np.ndarray,
    vel: np.ndarray,
    disp: np.ndarray,
    tau: np.ndarray,
    use: np.ndarray,
    harmonics=HARMONICS,
    dilate: int = 2,
    stiffness: float | None = None,
    damping: float | None = None,
    min_flight: int = 0,
) -> FreeFlightFit:
    """Fit the free-flight law and the table's motion, and split contact from free flight.

    Parameters
    ----------
    accel : numpy.ndarray
        Acceleration, polarity such that contact forces push ``-accel`` up.
    vel, disp : numpy.ndarray
        Integrated velocity and displacement (:func:`integrate_spectral`).
    tau : numpy.ndarray
        Time of each sample, forcing radians.
    use : numpy.ndarray
        Boolean mask of samples the fit may use (the integration's edges excluded).
    harmonics : tuple of int
        Forcing harmonics of the table's motion.
    dilate : int
        Samples added on each side of a contact before refitting the free flight.
    stiffness : float, optional
        Known ``k`` (``(f_n / f_f)**2`` from a given natural frequency); fitted when None.
    damping : float, optional
        Fix ``c`` (with `stiffness` given): on a near-sinusoidal orbit the free flight
        alone cannot tell ``c v`` from the table's motion at the forcing frequency.
    min_flight : int
        Free runs of at most this many samples join the contact in the impulse
        corrections: :data:`MIN_FLIGHT_SAMPLES` for a deconvolved record (its pulses'
        ripple), 0 (default) for a record as recorded.

    Returns
    -------
    FreeFlightFit
    """
    design = free_flight_design(vel, disp, tau, harmonics)
    target = -accel
    if stiffness is not None:  # move the known k x_i to the target side
        target = target - stiffness * disp
        design[:, 1] = 0.0
    if damping is not None:
        target = target - damping * vel
        design[:, 0] = 0.0
    coef, free, contact, sigma = robust_split(design, target, use, dilate)
    c = float(coef[0]) if damping is None else float(damping)
    k = float(coef[1]) if stiffness is None else float(stiffness)
    fitted = design[free] @ coef
    total = -accel[free]
    r2 = 1.0 - float(np.var(target[free] - fitted)) / max(float(np.var(total)), 1e-300)
    if k <= 0:
        table = np.zeros((len(harmonics), 2))
        offset = 0.0
    else:
        table = table_motion(coef[3:], k, c, harmonics)
        offset = float(coef[2]) / k
    s = np.zeros_like(tau)
    ds = np.zeros_like(tau)
    for i, ((ca, sa), m) in enumerate(zip(table, harmonics, strict=True)):
        cos, sin = design[:, 3 + 2 * i], design[:, 4 + 2 * i]  # cos m tau, sin m tau
        s += ca * cos + sa * sin
        ds += m * (sa * cos - ca * sin)
    x = disp + s + offset
    v = vel + ds
    if stiffness is not None and k > 0:
        fixed = _impulse_corrections(accel, v, x, tau, use, free, contact, k, damping, min_flight)
        if fixed is not None:
            corr, dcorr, c, r2 = fixed
            x, v = x + corr, v + dcorr
    return FreeFlightFit(
        stiffness=k,
        damping=c,
        table=table,
        offset=offset,
        displacement=x,
        velocity=v,
        force=-accel - (c * v + k * x),
        contact=contact,
        sigma=sigma,
        r2=r2,
    )
