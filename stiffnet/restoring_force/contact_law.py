r"""The contact law on the force-displacement map: onset, stiffness, dissipation, exponent.

The residual force of :mod:`~stiffnet.restoring_force.free_flight` is the
restraint's force on the mass. It is fitted by the Kelvin-Voigt power law of
the effects (``contact_damping``, ``hertz_contact``; docs/simulator.md)::

    F_c = max(0, K d_r (d / d_r)**p + c_c v)   if d = x - e > 0,   else 0

with ``e`` the contact onset (the gap), ``K`` the contact stiffness at the
reference penetration ``d_r`` (the median peak penetration, so that ``K`` is the
secant stiffness the impacts actually reach), ``c_c`` the contact damping and
``p`` the exponent (1: linear spring, 3/2: Hertz). The ``max`` matters: a damped
restraint pushes but never pulls, so the force returns to zero while the
penetration is still positive and the mass leaves early. A law without it (or a
contact duration read as ``pi / sqrt(K)``) mistakes the early release for a
stiffer contact: about 2x at a restitution coefficient of 0.5.

The stiffness ratio is then ``beta = K / k`` (eq. 12: restraint over primary
spring): a ratio of two slopes of the same map, so neither the sensor's gain nor
the natural frequency enters.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft, linalg, optimize, stats

#: Bounds of the contact exponent: from linear to well beyond Hertz (1.5). Below 1 (softer
#: than linear) a free exponent mostly absorbs reconstruction error at a damped onset.
EXPONENT_BOUNDS = (1.0, 3.0)
#: Starts of a fit through a band (:func:`fit_contact_law`), as multiples of the start's
#: stiffness: the band-limited map's own slope reads low by up to ~40 % behind a low-pass near
#: the contact (campaign records through their data sheets), and the fit through the band
#: can stall on the way from there.
BAND_START_GAINS = (1.0, 1.6)
#: Relative step of a forward difference: least_squares' own (``jac="2-point"``), the square
#: root of the machine epsilon, times ``max(1, |x|)``.
FORWARD_DIFFERENCE_STEP = float(np.sqrt(np.finfo(float).eps))


@dataclass(frozen=True)
class ContactLaw:
    """Fitted contact law (:func:`fit_contact_law`).

    Attributes
    ----------
    stiffness : float
        ``K``: secant contact stiffness at the reference penetration.
    onset : float
        ``e``: displacement where contact begins (the record's gain).
    damping : float
        ``c_c``: contact damping coefficient.
    exponent : float
        ``p``: 1 for a linear restraint, 1.5 for Hertz.
    reference_penetration : float
        ``d_r``: median peak penetration of the impacts.
    r2 : float
        Fraction of the contact force's variance explained (samples near impacts).
    sse : float
        Residual sum of squares.
    n_samples : int
        Samples fitted.
    """

    stiffness: float
    onset: float
    damping: float
    exponent: float
    reference_penetration: float
    r2: float
    sse: float = float("nan")
    n_samples: int = 0


def contact_force(
    disp: np.ndarray,
    vel: np.ndarray,
    stiffness: float,
    onset: float,
    damping: float,
    exponent: float = 1.0,
    reference_penetration: float = 1.0,
) -> np.ndarray:
    """The contact law: ``max(0, K d_r (d/d_r)**p + c_c v)`` where ``d = x - e > 0``, else 0."""
    d = np.maximum(np.asarray(disp) - onset, 0.0)
    elastic = stiffness * reference_penetration * (d / reference_penetration) ** exponent
    return np.where(d > 0, np.maximum(elastic + damping * np.asarray(vel), 0.0), 0.0)


def force_unit(force: np.ndarray) -> float:
    """The scale a map's fits run in: its force's rms (1 for none). least_squares' stopping
    tests are absolute, so a fit in the record's own unit stops elsewhere in g than in m/s^2;
    in this unit every record's fit stops at the same place."""
    return float(np.sqrt(np.mean(np.square(force)))) or 1.0


def linear_contact_start(
    force: np.ndarray, disp: np.ndarray, vel: np.ndarray, core: np.ndarray
) -> tuple[float, float, float]:
    """Starting values ``(K, e, c_c)``: least squares of ``F = K (x - e) + c_c v`` on the core."""
    a = np.column_stack([disp[core], np.ones(int(core.sum())), vel[core]])
    kc, b, cc = linalg.lstsq(a, force[core])[0]
    kc = float(kc)
    if kc <= 0:
        return float("nan"), float("nan"), float("nan")
    return kc, float(-b / kc), float(cc)


def profile_contact_start(
    force: np.ndarray, disp: np.ndarray, vel: np.ndarray, near: np.ndarray, n_grid: int = 24
) -> tuple[float, float, float]:
    """Starting values ``(K, e, c_c)`` by profiling the onset ``e`` over a grid.

    For each onset the linear law ``F = K (x - e) + c_c v`` is solved on the
    samples beyond it and the clipped law (:func:`contact_force`) scored on all
    samples near the impacts; the best onset wins. A strongly damped contact
    (zeta_c ~ 0.5) is mostly damping force at its start: a plain regression on the
    contact samples then gives a tiny ``K`` and a wrong onset, from which the
    least-squares fit does not recover.
    """
    f, x, v = force[near], disp[near], vel[near]
    best, best_sse = (float("nan"),) * 3, np.inf
    for e in np.quantile(x, np.linspace(0.3, 0.98, n_grid)):
        on = x > e
        if on.sum() < 3:
            continue
        a = np.column_stack([x[on] - e, v[on]])
        kc, cc = linalg.lstsq(a, f[on])[0]
        if not kc > 0:
            continue
        sse = float(np.sum((contact_force(x, v, kc, e, max(cc, 0.0)) - f) ** 2))
        if sse < best_sse:
            best, best_sse = (float(kc), float(e), float(max(cc, 0.0))), sse
    return best


class _LawResiduals:
    """The law's residual force (in the fit's unit) at a parameter vector ``(log K, e, c_c[, p])``
    or at each row of a batch of them, and its forward-difference Jacobian.

    Through a `band` the law's force over the whole record is filtered per ``rfft`` bin and
    read on the samples `near` the impacts; a batch is transformed in one call (``scipy.fft``
    along the last axis gives each row bit for bit what a transform of that row alone gives).
    The last point evaluated is kept: the solver asks for the Jacobian where it has just
    evaluated the residual, and the difference is taken from that same residual.
    """

    def __init__(self, x, v, f, dr, exponent, band, near) -> None:
        self.x, self.v, self.f, self.dr = x, v, f, dr
        self.exponent, self.band, self.near = exponent, band, near
        self._last: tuple[bytes, np.ndarray] | None = None

    def batch(self, thetas: np.ndarray) -> np.ndarray:
        """Residuals at each row of `thetas` (rows, n_params) -> (rows, samples)."""
        # a trial step may overflow the stiffness; its residual is then not finite and the
        # step is refused by the solver, so numpy's warnings would only reach the user
        with np.errstate(over="ignore", invalid="ignore"):
            out = np.array([
                contact_force(self.x, self.v, np.exp(t[0]), t[1], t[2],
                              t[3] if self.exponent is None else self.exponent, self.dr)
                for t in thetas
            ])  # fmt: skip
            if self.band is not None:
                n = self.x.size
                out = fft.irfft(fft.rfft(out, axis=-1) * self.band, n, axis=-1)[:, self.near]
        return out - self.f

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        r = self.batch(theta[None, :])[0]
        self._last = (np.asarray(theta, dtype=float).tobytes(), r)
        return r

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        """least_squares' forward-difference Jacobian at `theta` within the law's bounds."""
        key = np.asarray(theta, dtype=float).tobytes()
        r0 = self._last[1] if self._last is not None and self._last[0] == key else self(theta)
        return forward_difference_jacobian(self.batch, theta, r0, *_law_bounds(self.exponent))


def _law_bounds(exponent: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of ``(log K, e, c_c[, p])``: a damping that only dissipates, the exponent within
    :data:`EXPONENT_BOUNDS` where it is fitted."""
    free = exponent is None
    lo = [-np.inf, -np.inf, 0.0] + ([EXPONENT_BOUNDS[0]] if free else [])
    hi = [np.inf, np.inf, np.inf] + ([EXPONENT_BOUNDS[1]] if free else [])
    return np.array(lo), np.array(hi)


def forward_difference_steps(x0: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """least_squares' forward-difference steps (``jac="2-point"``): :data:`FORWARD_DIFFERENCE_STEP`
    times ``max(1, |x|)`` with the sign of ``x`` (+ at 0), reversed where it would leave the
    bounds and the other side has room, else cut to the farther bound."""
    x0 = np.asarray(x0, dtype=float)
    sign = (x0 >= 0).astype(float) * 2 - 1
    h = FORWARD_DIFFERENCE_STEP * sign * np.maximum(1.0, np.abs(x0))
    below, above = x0 - lower, upper - x0
    violated = (x0 + h < lower) | (x0 + h > upper)
    fitting = np.abs(h) <= np.maximum(below, above)
    h[violated & fitting] *= -1
    forward = (above >= below) & ~fitting
    h[forward] = above[forward]
    backward = (above < below) & ~fitting
    h[backward] = -below[backward]
    return h


def forward_difference_jacobian(
    batch, x0: np.ndarray, f0: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> np.ndarray:
    """The forward-difference Jacobian least_squares computes for ``jac="2-point"``, bit for
    bit, with the stepped points evaluated in one call.

    Parameters
    ----------
    batch : callable
        Residuals at each row of a (rows, n) array of points -> (rows, m).
    x0 : numpy.ndarray
        The point (n,).
    f0 : numpy.ndarray
        The residuals at `x0` (m,).
    lower, upper : numpy.ndarray
        Bounds on the parameters (n,).

    Returns
    -------
    numpy.ndarray
        (m, n); the transpose of a C-ordered array, as scipy lays it out.
    """
    x0 = np.asarray(x0, dtype=float)
    h = forward_difference_steps(x0, lower, upper)
    stepped = np.tile(x0, (x0.size, 1))
    idx = np.arange(x0.size)
    stepped[idx, idx] = x0 + h
    dx = (x0 + h) - x0
    # scipy fills an (n, m) C-ordered array and returns its transpose; the solver's products
    # with the Jacobian take another path (and round otherwise) on another layout
    return np.ascontiguousarray((batch(stepped) - f0) / dx[:, None]).T


def fit_contact_law(
    force: np.ndarray,
    disp: np.ndarray,
    vel: np.ndarray,
    near: np.ndarray,
    start: tuple[float, float, float],
    reference_penetration: float,
    exponent: float | None = None,
    max_nfev: int = 60,
    band: np.ndarray | None = None,
) -> ContactLaw:
    """Least-squares fit of the contact law on the samples near impacts.

    With a `band` the law is fitted forward through it: the law's force over the whole
    record is passed through the band (per ``rfft`` bin) before it meets the residual force
    on the samples near impacts. The residual force of a sensor chain's inverse keeps only
    the band the record carries above its noise (:func:`~.band.kept_band`): near the contact's
    frequency the rounded pulses put force where the penetration is small and the map's
    slope reads soft (an 85 Hz 4th-order low-pass under a 62 Hz contact, 2 % noise: beta
    27 for 41.6), while the same band applied to the law's force reads the law itself
    (41.2).

    The solver uses forward differences: the law's analytic Jacobian, tried, reached other end
    points (a rig record behind an 80 Hz 2nd-order low-pass then chose another chain and read
    beta 13.4 for 30). They are least_squares' own (:func:`forward_difference_jacobian`), its
    steps evaluated in one batch: through a band one ``rfft`` of all of them.

    Parameters
    ----------
    force, disp, vel : numpy.ndarray
        Residual force and reconstructed state on the samples to fit.
    near : numpy.ndarray
        Boolean mask of the samples used (in contact and a margin around).
    start : tuple of float
        Starting ``(K, e, c_c)`` (:func:`linear_contact_start`).
    reference_penetration : float
        ``d_r`` at which ``K`` is the secant stiffness.
    exponent : float, optional
        Fix ``p`` (None fits it within :data:`EXPONENT_BOUNDS`).
    max_nfev : int
        Bound on the residual evaluations (the law is not smooth at onset and release).
    band : numpy.ndarray, optional
        Complex response per ``rfft`` bin of the full arrays (what the record keeps of the
        true acceleration), ``numpy.fft.rfft``'s length for ``force.size``; None fits the
        law as it is.

    Returns
    -------
    ContactLaw
    """
    # the law is homogeneous: force, penetration and velocity scale together, K, c_c and p
    # do not
    unit = force_unit(force[near])
    f = force[near] / unit
    kc0, e0, cc0 = start
    e0 = e0 / unit
    dr = reference_penetration / unit
    x, v = (disp / unit, vel / unit) if band is not None else (disp[near] / unit, vel[near] / unit)
    residuals = _LawResiduals(x, v, f, dr, exponent, band, near)

    lo, hi = _law_bounds(exponent)
    # through a band the start (the map's own slope) reads soft: a stiffer start as well
    res = None
    for gain in (1.0,) if band is None else BAND_START_GAINS:
        theta0 = [np.log(gain * kc0), e0, max(cc0, 0.0)] + ([1.0] if exponent is None else [])
        # a trial step to a huge stiffness (log K in the hundreds) leaves a residual that is
        # finite but whose square is not: the solver's cost is then inf and the step refused,
        # as a non-finite residual's is, so numpy's overflow warning would only reach the user
        with np.errstate(over="ignore"):
            sol = optimize.least_squares(
                residuals, np.clip(theta0, lo, hi), jac=residuals.jacobian, bounds=(lo, hi),
                x_scale="jac", max_nfev=max_nfev,
            )  # fmt: skip
        if res is None or sol.cost < res.cost:
            res = sol
    th = res.x
    resid = res.fun
    r2 = 1.0 - float(np.sum(resid**2)) / max(float(np.sum((f - f.mean()) ** 2)), 1e-300)
    return ContactLaw(
        stiffness=float(np.exp(th[0])),
        onset=float(th[1]) * unit,
        damping=float(th[2]),
        exponent=float(th[3]) if exponent is None else float(exponent),
        reference_penetration=float(reference_penetration),
        r2=r2,
        sse=float(np.sum(resid**2)) * unit**2,
        n_samples=int(f.size),
    )


def exponent_matters(linear: ContactLaw, free: ContactLaw, level: float = 1e-3) -> bool:
    """Rule: keep the fitted exponent only if it lowers the residual significantly (F-test).

    With a few samples per impact and noise, a free exponent wanders (0.5-1.2
    on linear contacts at 5 % noise) and drags the secant stiffness with it;
    the linear law is kept unless the extra parameter earns its place.
    """
    dof = free.n_samples - 4
    if dof < 1 or not free.sse < linear.sse:
        return False
    f_stat = (linear.sse - free.sse) / max(free.sse / dof, 1e-300)
    return bool(f_stat > stats.f.ppf(1.0 - level, 1, dof))


def equivalent_linear_band(exponent: float) -> tuple[float, float]:
    """Rule: the linear springs a power law ``F = K d_r (d / d_r)^p`` stands for at its
    reference penetration ``d_r``, as factors of its secant stiffness ``K`` there.

    A stiffening contact has no one stiffness, and the record does not say which linear
    spring its beta should be (a manifest's may be a secant at another penetration, a tangent,
    an energy match): at the impacts' own penetration the spring that stores the same energy
    is ``2 / (p + 1) K`` and the one of the same slope ``p K``; the secant (the same force)
    lies between. The linear law (``p = 1``) gives ``(1, 1)``.
    """
    p = max(float(exponent), 1.0)
    return 2.0 / (p + 1.0), p
