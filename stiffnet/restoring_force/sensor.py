"""The sensor chain, undone before integrating: charge-amplifier high-pass, mounted resonance.

The restoring-force map needs the true acceleration; the recorded one went
through the sensor chain (``sensor_dynamics``, docs/simulator.md). Two stages
are identified from the record itself and inverted:

**High-pass.** A charge amplifier's first-order high-pass ``H(s) = s / (s + w_h)`` turns the
true acceleration ``a`` into the recorded ``y`` with ``y' + w_h y = a'``, so::

    a = y + w_h Y + C,        Y(tau) = int_0^tau y

exactly, start-up transient included (the constant ``C`` is dropped by the
integration). Everything downstream is linear in ``a``: the integrals are
``x = x(y) + w_h x(Y)``, ``v = v(y) + w_h v(Y)``, and the free-flight law
``-a = c v + k x + table + d`` (:mod:`~stiffnet.restoring_force.free_flight`)
becomes, with ``k`` known,

    -y - k x(y) = c v(y) + w_h (Y + k x(Y)) + (c w_h) v(Y) + table + d,

a regression that is still linear once ``c w_h`` is its own coefficient.
One least-squares fit with the contacts split off as outliers gives ``w_h``
and its standard error, with no search over corners. A corner within two
standard errors of zero, or one that hardly shrinks the free flight's scatter,
is read as no high-pass.

The filter's steady-state effect on the free flight is a phase lead of
``atan(w_h / m)`` at the forcing harmonic ``m`` (6 deg for 1 Hz under a 10 Hz
forcing), which the table's fitted sinusoids partly absorb; the start-up
transient ``C e^{-w_h tau}`` of a record that begins with the filter out of
equilibrium is what identifies ``w_h`` best.

**Mounted resonance.** ``H_r(s) = w_r^2 / (s^2 + 2 zeta_r w_r s + w_r^2)``
rings at ``f_r`` after every impact: in free flight the residual force of the
linear law is that ringing, a decaying second-order mode, so an AR(2) fit of
the residual just after the impacts gives its pole, hence ``f_r`` and
``zeta_r`` (:func:`ringing_mode`). Where the ringing dominates that residual
the resonance is divided out in the frequency domain
(:func:`undo_resonance`), tapered above ``2 f_r`` where the sensor left only
noise. A resonance far above the contact's band leaves no ringing worth the
name and is left alone; the anti-alias low-pass cannot be seen this way and is
not undone (its delay is shared by force and displacement; its rounding of
spikes sampled with a few points is the estimate's residual bias).
"""

from __future__ import annotations

import numpy as np
from scipy import integrate

from stiffnet.restoring_force.free_flight import HARMONICS, free_flight_design, robust_split
from stiffnet.restoring_force.reconstruct import integrate_spectral

#: Largest corner fitted, forcing frequencies (the priors' 2 Hz under a 7.6 Hz forcing is 0.26).
MAX_CORNER = 0.5
#: A fitted corner is kept only beyond this many standard errors from zero.
CORNER_SIGNIFICANCE = 2.0
#: ... and only if it shrinks the free flight's robust scatter by this factor (a real
#: high-pass's start-up transient: 1.3-100x on the priors; spurious corners: <= 1.2x).
CORNER_GAIN = 1.3


def cumulative(y: np.ndarray, dtau: float) -> np.ndarray:
    """``int_0^tau y`` by the trapezoid rule (the bilinear high-pass's own discretisation)."""
    return integrate.cumulative_trapezoid(y, dx=dtau, initial=0.0)


def undo_highpass(y: np.ndarray, dtau: float, corner: float) -> np.ndarray:
    """Invert a first-order high-pass at ``corner`` (forcing frequencies): ``y + w_h int_0^t y``.

    The inverse runs in the time domain from the first sample, so that it also
    removes the start-up transient of a filter out of equilibrium when the
    record begins; its constant of integration is dropped by the integration.
    """
    if corner <= 0:
        return y
    return y + corner * cumulative(y, dtau)


def fit_highpass_corner(
    y: np.ndarray,
    dtau: float,
    tau: np.ndarray,
    use: np.ndarray,
    stiffness: float | None = None,
    harmonics=HARMONICS,
    sigma_plain: float | None = None,
) -> tuple[float, float, float]:
    """Corner ``w_h`` of a first-order high-pass in forcing frequencies, and its standard error.

    Parameters
    ----------
    y : numpy.ndarray
        Recorded acceleration, polarity such that contact forces push ``-y`` up.
    dtau : float
        Sampling step, forcing radians.
    tau : numpy.ndarray
        Time of each sample, forcing radians.
    use : numpy.ndarray
        Samples the fit may use (the integration's edges excluded).
    stiffness : float, optional
        Known free-flight stiffness ``k = (f_n / f_f)**2``; fitted alongside when None.
    harmonics : tuple of int
        Forcing harmonics of the table's motion.
    sigma_plain : float, optional
        Robust free-flight scatter without a high-pass (``FreeFlightFit.sigma`` of
        the same record); computed here when None.

    Returns
    -------
    corner, stderr : float
        Least-squares ``w_h`` (any sign; the caller's rule keeps it or not) and its
        standard error from the free-flight scatter.
    gain : float
        Robust free-flight scatter without the high-pass terms over that with them.
    """
    big_y = cumulative(y, dtau)
    vel, disp = integrate_spectral(y, dtau)
    vel_y, disp_y = integrate_spectral(big_y, dtau)
    base = free_flight_design(vel, disp, tau, harmonics)  # [v, x, 1, cos, sin, ...]
    if stiffness is not None:
        target = -y - stiffness * disp
        extra = [big_y + stiffness * disp_y, vel_y]
        design = np.column_stack([base[:, :1], *[e[:, None] for e in extra], base[:, 2:]])
        j = 1
    else:
        target = -y
        design = np.column_stack([base[:, :2], big_y, disp_y, vel_y, base[:, 2:]])
        j = 2
    coef, free, _, sigma = robust_split(design, target, use)
    if sigma_plain is None:  # the free-flight fit without the high-pass terms
        plain = np.delete(design, range(j, j + (2 if stiffness is not None else 3)), axis=1)
        sigma_plain = robust_split(plain, target, use)[3]
    a = design[free]
    norms = np.sqrt(np.einsum("ij,ij->j", a, a))
    norms[norms == 0] = 1.0
    scaled = a / norms
    try:
        cov = np.linalg.inv(scaled.T @ scaled)
        stderr = float(sigma * np.sqrt(max(cov[j, j], 0.0)) / norms[j])
    except np.linalg.LinAlgError:
        stderr = float("inf")
    return float(coef[j]), stderr, sigma_plain / max(sigma, 1e-300)


def highpass_rule(corner: float, stderr: float, gain: float) -> float:
    """Rule: keep a fitted corner when it is significant, in range and shrinks the free-flight
    scatter by :data:`CORNER_GAIN` (a systematic misfit of a noise-free record makes tiny
    standard errors: significance alone picks spurious corners), else no high-pass (0)."""
    if not np.isfinite(corner) or corner <= CORNER_SIGNIFICANCE * stderr or gain < CORNER_GAIN:
        return 0.0
    return float(min(corner, MAX_CORNER))


#: The AR(2) pole must explain this fraction of the post-impact residual to count as ringing.
RINGING_FRACTION = 0.8
#: ... and be this lightly damped (a sensor's mount: zeta_r 0.01-0.1).
RINGING_MAX_DAMPING = 0.2
#: Post-impact window of the AR(2) fit, natural periods.
RINGING_WINDOW = 0.3
#: Without contacts to compare with, a ring must be this many times the natural frequency.
RINGING_MIN_FN = 5.0
#: The equaliser's taper: a fourth-order roll-off at this multiple of f_r.
TAPER = 2.0


def ringing_mode(
    force: np.ndarray, contact: np.ndarray, window: int, order: int = 4
) -> tuple[float, float, float] | None:
    """Frequency (radians per sample), damping ratio and strength of the post-impact ringing.

    Least squares of an AR(`order`) model ``r[n] = sum_i a_i r[n-i]`` of the
    residual force's first difference in the `window` samples after each
    contact; each complex root ``z`` of its polynomial is ``exp(s)`` with
    ``s = -zeta w + i w sqrt(1 - zeta^2)``, and the lightly damped one with the
    strongest AR spectral peak is the mount's (order 4: the contact's own slow
    tail, or the noise the difference lifts, takes the other pair).

    Returns
    -------
    (w, zeta, fraction) or None
        ``fraction``: share of the windows' residual variance the mode explains;
        None without complex poles or with too few samples.
    """
    ends = np.flatnonzero(contact[:-1] & ~contact[1:]) + 1
    near = np.zeros(force.size, dtype=bool)
    for e in ends:
        near[e : e + window] = True
    near &= ~contact
    near[1:] &= near[:-1]  # the first difference needs the sample before
    n = np.flatnonzero(near[2:] & near[1:-1] & near[:-2]) + 2
    if n.size < 8:
        return None
    # on the first difference: the slow misfit of the reconstruction drops out, the ring stays
    r = np.diff(force, prepend=force[0])
    n = n[n >= order]
    if n.size < 4 * order:
        return None
    a = np.column_stack([r[n - i] for i in range(1, order + 1)])
    coef = np.linalg.lstsq(a, r[n], rcond=None)[0]
    fraction = 1.0 - float(np.var(r[n] - a @ coef)) / max(float(np.var(r[n])), 1e-300)
    z = np.roots(np.r_[1.0, -coef])
    z = z[(np.abs(z.imag) > 0) & (np.abs(z) < 1)]
    if z.size == 0:
        return None
    s = np.log(np.abs(z)) + 1j * np.abs(np.angle(z))
    zeta = -s.real / np.abs(s)
    # the mount: the lightly damped pair with the strongest AR spectral peak (the other pair
    # models the contact's tail, or the noise the difference lifts near Nyquist)
    light = np.flatnonzero(zeta < RINGING_MAX_DAMPING)
    if not light.size:
        i = int(np.argmin(zeta))
    else:
        lags = np.arange(1, order + 1)
        a_of_w = 1.0 - np.exp(-1j * np.outer(s.imag[light], lags)) @ coef
        i = light[int(np.argmin(np.abs(a_of_w)))]
    return float(abs(s[i])), float(zeta[i]), fraction


def resonance_rule(
    mode: tuple[float, float, float] | None, samples_per_contact: float, natural_samples: float
) -> tuple[float, float] | None:
    """Rule: ``(w_r, zeta_r)`` (radians per sample) when a light ringing dominates the
    post-impact residual and is at least twice as fast as the contact itself (a contact of
    ``n`` samples is half a cycle of ``pi / n``: slower "ringing" is the contact's own tail);
    when the contacts could not be split (a ring that dominates the free flight), at least
    :data:`RINGING_MIN_FN` times the natural frequency (``natural_samples`` per period)."""
    if mode is None:
        return None
    w, zeta, fraction = mode
    if fraction < RINGING_FRACTION or not 0 < zeta < RINGING_MAX_DAMPING or w >= 0.9 * np.pi:
        return None
    slowest = (
        2 * np.pi / samples_per_contact
        if samples_per_contact > 0
        else 2 * np.pi * RINGING_MIN_FN / natural_samples
    )
    if w < slowest:
        return None
    return w, zeta


def undo_resonance(y: np.ndarray, w_r: float, zeta_r: float) -> np.ndarray:
    """Divide a sampled record by the mounted resonance (bilinear, prewarped) and taper.

    The digital resonance is the bilinear image of the analog one, so at the
    digital frequency ``w`` its inverse is ``1 - (W/w_r')^2 + 2 i zeta W / w_r'``
    with ``W = 2 tan(w/2)`` and ``w_r' = 2 tan(w_r/2)``; a zero-phase fourth-order
    taper at ``TAPER w_r'`` (in ``W``: it must beat the tan's growth near
    Nyquist, where the bilinear resonance has its double zero) keeps the noise
    the inverse would amplify above the resonance in bounds. The record is
    treated as periodic (its ends are not used).
    """
    w = np.fft.rfftfreq(y.size) * 2 * np.pi
    big_w = 2 * np.tan(np.minimum(w, np.pi * 0.999) / 2)
    wr = 2 * np.tan(w_r / 2)
    inverse = 1 - (big_w / wr) ** 2 + 2j * zeta_r * big_w / wr
    taper = 1.0 / np.sqrt(1.0 + (big_w / (TAPER * wr)) ** 8)  # beats the tan's growth
    return np.fft.irfft(np.fft.rfft(y) * inverse * taper, y.size)
