"""The geometric stiffness estimate, end to end (paper section 5).

:func:`geometric_estimate` chains: normalisation, dominant period,
Savitzky-Golay smoothing (2nd order, sections 2 and 5.1), embedding delay and
dimension (section 4.1), delay embedding, tangent vectors (eqs 4-6),
separation of contact and free flight (Fig. 8), inclinations before and after
each impact (eqs 7-10, Table 1) and the calibration to beta and a class
(Fig. 11).

Everything that has a time scale is tied to the **dominant period** ``T`` of
the record (the forcing period, from the velocity spectrum): the smoothing
window (``0.08 T``), the tangent lag (``0.01 T``), the delay (``0.18 T`` by
default) and the approach length (one delay). The inclinations are then the
same at any sampling rate that resolves the spikes, which is what lets one
calibration serve recordings sampled at 50-500 times the natural frequency.

Why the delay is not the AMI minimum by default: the inclinations are
ratios of the signal's slope during or just before an impact (z) to its slope
``2 tau`` earlier (x), so they move with ``tau / T``. On these spiky periodic
signals the histogram AMI is jagged and its first (prominent) minimum wanders
between 0.03 T and 0.33 T from one parameter set to the next (12-34 samples on
the paper's own parameter set at 100 samples per natural period), which would
scramble the inclination-stiffness trend. ``delay="period"`` (default) uses
``tau = 0.18 T``: the paper's delay of 17 samples ("first minimum mutual
information around 17") at 100 samples per natural period (``T`` = 95 samples
at w = 1.05), the sampling at which the robust AMI rule gives a median of 16
samples over the paper's sixteen betas (docs/paper_reproduction.md; 0.23 T
matches Table 1's "before" angles better but calibrates slightly worse).
``delay="ami"`` uses the robust AMI rule of
:func:`stiffnet.nlts.estimate_delay` instead (the calibration was not fitted
with it), and an int fixes the delay.

Polarity and gain: the paper's sensor shows impacts as positive spikes, ours
as negative ones. Nothing here depends on the sign: tangent magnitudes, the
derivative impact indicator and the inclinations ``atan(|dz| / |dx|)`` are all
unchanged under ``s -> -s``; the detected polarity is only reported. The
record is standardised first, so a gain changes nothing either.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from stiffnet.errors import ConfigError, SignalError
from stiffnet.geometry.calibration import (
    CALIBRATION_FILE,
    NO_CONTACT,
    GeometricCalibration,
    load_calibration,
)
from stiffnet.geometry.inclination import (
    OrbitInclinations,
    check_method,
    gradient_inclinations,
    polynomial_inclinations,
)
from stiffnet.geometry.orbit import (
    describe_pattern,
    flight_periods,
    impact_pattern,
    is_period1,
    position_summary,
)
from stiffnet.geometry.separation import ContactSeparation, separate_contact
from stiffnet.geometry.tangent import tangent_lag, tangent_magnitudes, tangent_vectors
from stiffnet.nlts import (
    detect_impacts,
    estimate_delay,
    estimate_dimension,
    savgol_smooth,
)
from stiffnet.nlts._validate import as_signal
from stiffnet.nlts.embedding import embed_unchecked
from stiffnet.recordings.base import check_rate
from stiffnet.shipped import shipped_file

#: Delay as a fraction of the dominant period (see the module notes).
DELAY_FRACTION = 0.18
#: Savitzky-Golay window as a fraction of the dominant period (odd, >= 5 samples).
SMOOTHING_FRACTION = 0.08
#: Cao's method runs on at most this many samples (it is the slowest step).
CAO_MAX_SAMPLES = 8192
#: Orbits needed to report inclinations.
MIN_ORBITS = 2
#: Shortest record, in dominant periods.
MIN_PERIODS = 3.0

_CALIBRATION_CACHE: dict[Path, GeometricCalibration] = {}


def dominant_period(x: ArrayLike) -> float:
    """Dominant period of an acceleration record in samples: the velocity spectrum's peak.

    The periodogram of the mean-removed, Hann-windowed signal is divided by
    ``f**2`` - the spectrum of the velocity - and its largest peak (at least
    two cycles per record) is refined by a parabola through the log-power of
    the three bins around it.

    Why the velocity: impacts put much of the acceleration's power into
    harmonics, and orbits with two impacts every three forcing periods have
    their strongest acceleration line at ``4 w / 3`` or their autocorrelation
    peak at the shorter impact interval; integrating once divides the
    harmonics by ``k**2`` and leaves the forcing line on top. On 60 simulated
    windows of the default domain (16 natural periods, 0-9 % noise, period-1
    and period-3 orbits) the peak was within 5 % of the forcing period every
    time; the autocorrelation's first peak missed 10 times, the plain
    acceleration spectrum 3 times.

    Parameters
    ----------
    x : array_like
        Acceleration record.

    Returns
    -------
    float
        Period in samples (fractional).

    Raises
    ------
    SignalError
        If the signal is invalid or its spectrum has no peak above the lowest bins.
    """
    a = as_signal(x, 16)
    n = a.size
    spec = np.abs(np.fft.rfft((a - a.mean()) * np.hanning(n))) ** 2
    k = np.arange(spec.size, dtype=np.float64)
    vel = np.zeros_like(spec)
    vel[1:] = spec[1:] / k[1:] ** 2
    # Bins 0-1 (less than two cycles) hold trends, not the oscillation.
    if vel.size < 4 or not np.any(vel[2:-1] > 0):
        raise SignalError("no oscillation found in the record")
    j = 2 + int(np.argmax(vel[2:-1]))
    y0, y1, y2 = np.log(np.maximum(vel[j - 1 : j + 2], 1e-300 * vel[j]))
    den = y0 - 2 * y1 + y2
    shift = float(np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5)) if den < 0 else 0.0
    return float(n / (j + shift))


@dataclass(frozen=True)
class GeometricResult:
    """Result of :func:`geometric_estimate`.

    Attributes
    ----------
    contact_detected : bool
        Whether the window contains impacts the method can use.
    geometric_class : str or None
        ``"soft"``, ``"medium"``, ``"hard"``, ``"very_hard"``, ``"no_contact"``,
        or None if no calibration was used.
    geometric_beta : float or None
        Stiffness ratio estimate; None without contact or calibration.
    inclination_before_deg, inclination_after_deg : float
        Mean inclinations of the free-flight (before impact) and contact
        (after impact) planes in the x-z projection, by `method`; NaN
        without contact.
    orbit_before_deg, orbit_after_deg : numpy.ndarray
        The per-orbit inclinations behind the means.
    gradient_before_deg, gradient_after_deg : float
        Means by the gradient approach (eqs 9-10), whatever `method`.
    polynomial_before_deg, polynomial_after_deg : float
        Means by the polynomial-fit approach (Table 1), whatever `method`.
    method : str
        Inclination estimator fed to the calibration.
    delay, dimension : int
        Embedding delay (samples) and dimension used.
    delay_rule, dimension_rule : str
        How they were chosen.
    period_samples : float
        Dominant period in samples; ``dominant_frequency_hz`` in Hz.
    smoothing_window, tangent_lag : int
        Savitzky-Golay window and the tangent lag ``n`` (samples).
    impacts : numpy.ndarray
        Sample indices of impacts from :func:`stiffnet.nlts.detect_impacts`.
    n_orbits : int
        Orbits (impacts with a usable approach) behind the inclinations.
    threshold : float
        Contact threshold on tangent magnitudes of the standardised signal
        (``inf`` without contact).
    contact_fraction : float
        Fraction of tangents flagged as contact.
    polarity : int
        -1 if the impact spikes point down (our simulator), +1 if up (the
        paper's sensor), 0 without contact. Informational only.
    separation : ContactSeparation
        Histogram and criteria of the contact separation.
    reason : str
        One line: why contact was or was not detected, and the orbit when it is
        not the period-1 orbit the calibration and Table 1 describe.
    impact_pattern : tuple of int or None
        ``(n, m)``: n impacts every m forcing periods
        (:func:`stiffnet.geometry.orbit.impact_pattern`); None without contact or
        without a repeating pattern.
    orbit_flight_periods : numpy.ndarray
        Per orbit (as `orbit_before_deg`): the free flight before its impact in
        forcing periods, its position in the orbit
        (:func:`stiffnet.geometry.orbit.flight_periods`; NaN for the first).
    calibration_orbit : str or None
        Which map of the calibration gave beta: ``"period1"`` or ``"period_n"``
        (:meth:`~stiffnet.geometry.calibration.GeometricCalibration.for_orbit`);
        None without contact or calibration.
    """

    contact_detected: bool
    geometric_class: str | None
    geometric_beta: float | None
    inclination_before_deg: float
    inclination_after_deg: float
    orbit_before_deg: np.ndarray
    orbit_after_deg: np.ndarray
    gradient_before_deg: float
    gradient_after_deg: float
    polynomial_before_deg: float
    polynomial_after_deg: float
    method: str
    delay: int
    delay_rule: str
    dimension: int
    dimension_rule: str
    period_samples: float
    dominant_frequency_hz: float
    smoothing_window: int
    tangent_lag: int
    impacts: np.ndarray
    n_orbits: int
    threshold: float
    contact_fraction: float
    polarity: int
    separation: ContactSeparation = field(repr=False)
    reason: str = ""
    impact_pattern: tuple[int, int] | None = None
    orbit_flight_periods: np.ndarray = field(default_factory=lambda: np.empty(0), repr=False)
    calibration_orbit: str | None = None

    def positions(self) -> list[dict[str, float]]:
        """Inclinations grouped by position in the orbit
        (:func:`stiffnet.geometry.orbit.position_summary`)."""
        return position_summary(
            self.orbit_flight_periods, self.orbit_before_deg, self.orbit_after_deg
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready summary (no arrays except the per-orbit angles and impacts)."""

        def num(v: float) -> float | None:
            return float(v) if np.isfinite(v) else None

        return {
            "contact_detected": self.contact_detected,
            "geometric_class": self.geometric_class,
            "geometric_beta": self.geometric_beta,
            "inclination_before_deg": num(self.inclination_before_deg),
            "inclination_after_deg": num(self.inclination_after_deg),
            "orbit_before_deg": [float(v) for v in self.orbit_before_deg],
            "orbit_after_deg": [float(v) for v in self.orbit_after_deg],
            "gradient_before_deg": num(self.gradient_before_deg),
            "gradient_after_deg": num(self.gradient_after_deg),
            "polynomial_before_deg": num(self.polynomial_before_deg),
            "polynomial_after_deg": num(self.polynomial_after_deg),
            "method": self.method,
            "delay": self.delay,
            "delay_rule": self.delay_rule,
            "dimension": self.dimension,
            "dimension_rule": self.dimension_rule,
            "period_samples": self.period_samples,
            "dominant_frequency_hz": self.dominant_frequency_hz,
            "smoothing_window": self.smoothing_window,
            "tangent_lag": self.tangent_lag,
            "impacts": [int(i) for i in self.impacts],
            "n_orbits": self.n_orbits,
            "threshold": num(self.threshold),
            "contact_fraction": self.contact_fraction,
            "polarity": self.polarity,
            "reason": self.reason,
            "impact_pattern": list(self.impact_pattern) if self.impact_pattern else None,
            "impact_positions": self.positions(),
            "calibration_orbit": self.calibration_orbit,
        }


def smoothing_window(period: float, fraction: float = SMOOTHING_FRACTION) -> int:
    """Rule: odd Savitzky-Golay window of about ``fraction * period`` samples, at least 5."""
    return max(5, 2 * int(round(0.5 * fraction * period)) + 1)


def _resolve_calibration(
    calibration: GeometricCalibration | str | Path | None,
) -> GeometricCalibration | None:
    if calibration is None or isinstance(calibration, GeometricCalibration):
        return calibration
    path = shipped_file(CALIBRATION_FILE) if calibration == "default" else Path(calibration)
    path = path.resolve()
    if path not in _CALIBRATION_CACHE:
        _CALIBRATION_CACHE[path] = load_calibration(path)
    return _CALIBRATION_CACHE[path]


def impact_polarity(s: np.ndarray, impacts: np.ndarray) -> int:
    """+1 if the samples at the impacts lie above the median, -1 if below."""
    if impacts.size == 0:
        return 0
    lo, hi = max(0, impacts.min() - 1), impacts.max() + 2
    # the derivative peaks on a spike's flank: look at the extreme within +-2 samples
    win = np.clip(impacts[:, None] + np.arange(-2, 3)[None, :], 0, s.size - 1)
    dev = s[win] - np.median(s[lo:hi])
    ext = dev[np.arange(dev.shape[0]), np.argmax(np.abs(dev), axis=1)]
    return 1 if float(np.median(ext)) > 0 else -1


def embedding_delay(s: np.ndarray, period: float, delay: int | str) -> tuple[int, str]:
    """The embedding delay in samples and the rule that gave it.

    ``"period"``: ``round(0.18 T)`` of the dominant period ``T`` (the module notes say
    why); ``"ami"``: the robust AMI rule; an int: that many samples.
    """
    if not isinstance(delay, str):
        if int(delay) < 1:
            raise ConfigError(f"delay must be >= 1, got {delay}")
        return int(delay), "given"
    if delay == "period":
        return max(1, int(round(DELAY_FRACTION * period))), "period_0.18"
    if delay == "ami":
        est = estimate_delay(s, max_lag=min(s.size // 2, int(period)))
        return est.value, est.rule
    raise ConfigError(f"unknown delay rule {delay!r}; expected 'period', 'ami' or an int")


def embedding_dimension(s: np.ndarray, tau: int, dimension: int | str) -> tuple[int, str]:
    """The embedding dimension and the rule that gave it (Cao on at most 8192 samples)."""
    if not isinstance(dimension, str):
        if int(dimension) < 1:
            raise ConfigError(f"dimension must be >= 1, got {dimension}")
        return int(dimension), "given"
    if dimension != "cao":
        raise ConfigError(f"unknown dimension rule {dimension!r}; expected 'cao' or an int")
    try:
        est = estimate_dimension(s[:CAO_MAX_SAMPLES], tau, max_dim=6, method="cao")
    except SignalError as exc:  # e.g. an exactly predictable segment
        return 3, f"default 3 (cao failed: {exc})"
    return est.value, est.rule


def _period_n_caveat(pattern: Any, cal: GeometricCalibration | None) -> str:
    """Why the inclinations of an orbit other than period-1 read the orbit (see orbit.py)."""
    which = (
        "calibrated for orbits other than period-1"
        if cal is not None and cal.period_n is not None
        else "the calibration and Table 1 are for one impact per period"
    )
    return (
        f"orbit: {describe_pattern(pattern)} - the 'before' inclination reads "
        f"the orbit as much as beta ({which})"
    )


def _both_inclinations(
    y: np.ndarray,
    v: np.ndarray,
    sep: Any,
    impacts: np.ndarray,
    tau: int,
    lag: int,
    polynomial_degree: int,
) -> tuple[OrbitInclinations | None, OrbitInclinations | None, bool, str]:
    """Gradient and polynomial inclinations (eqs 7-10) of the impacting orbits.

    Returns both (None without contact), whether contact stands once impacts and
    complete orbits are counted, and the reason when it does not.
    """
    reason = sep.reason
    if not sep.contact_detected:
        return None, None, False, reason
    if impacts.size == 0:
        return None, None, False, "no impacts found by detect_impacts (derivative indicator)"
    approach = max(3, tau)
    merge_gap = max(lag, tau // 2)
    hit = np.abs(v[:, 2]) > sep.threshold
    grad = gradient_inclinations(v, sep.mask, hit, approach, merge_gap)
    poly = polynomial_inclinations(
        y[:, :3], sep.mask, hit, approach, lag, merge_gap, polynomial_degree
    )
    if grad.n_orbits < MIN_ORBITS:
        reason = f"{grad.n_orbits} complete orbit(s) with an impact, {MIN_ORBITS} needed"
        return grad, poly, False, reason
    return grad, poly, True, reason


def _smoothed(a: np.ndarray) -> tuple[np.ndarray, float, int]:
    """The standardised record (every later step is then independent of the gain),
    smoothed: ``(smoothed, dominant period in samples, smoothing window)``."""
    a = (a - a.mean()) / a.std()
    period = dominant_period(a)
    if a.size < MIN_PERIODS * period:
        raise SignalError(
            f"acceleration is too short: its dominant period is {period:.1f} samples, so "
            f"{a.size} samples hold {a.size / period:.1f} cycles; at least {MIN_PERIODS:g} needed"
        )
    win = smoothing_window(period)
    return savgol_smooth(a, win, 2), period, win


def _embedded(
    s: np.ndarray, period: float, delay: int | str, dimension: int | str
) -> tuple[np.ndarray, int, str, int, str]:
    """The delay embedding the inclinations are read in: ``(points, delay, its rule,
    dimension used (at least 3: the x-z projection), its rule)``."""
    tau, delay_rule = embedding_delay(s, period, delay)
    m, dim_rule = embedding_dimension(s, tau, dimension)
    m_used = max(3, m)
    if s.size < (m_used - 1) * tau + 3 * period:
        raise SignalError(
            f"acceleration is too short to embed with dim={m_used}, delay={tau} and keep "
            f"three periods of {period:.1f} samples"
        )
    return embed_unchecked(s, m_used, tau), tau, delay_rule, m_used, dim_rule


def _calibrated(
    chosen: OrbitInclinations | None,
    cal: GeometricCalibration | None,
    pattern: Any,
) -> tuple[float | None, str | None, str | None]:
    """``(beta, class, calibration orbit)`` of the chosen inclinations: no contact is
    ``no_contact``; no calibration gives no beta; a period-n orbit its own calibration."""
    if chosen is None:
        return None, NO_CONTACT, None
    if cal is None:
        return None, None, None
    used = cal.for_orbit(pattern)
    b, c = used.predict((chosen.mean_before, chosen.mean_after))
    return float(b), str(c), "period1" if used is cal else "period_n"


def _chosen_inclinations(
    chosen: OrbitInclinations | None, impacts: np.ndarray, tau: int, period: float
) -> dict[str, Any]:
    """The result's fields of the chosen inclinations: means, per orbit, the orbits'
    flight periods (NaN and empty without contact)."""
    if chosen is None:
        empty = np.empty(0)
        return dict(inclination_before_deg=float("nan"), inclination_after_deg=float("nan"),
                    orbit_before_deg=empty, orbit_after_deg=empty, n_orbits=0,
                    orbit_flight_periods=np.empty(0))  # fmt: skip
    return dict(
        inclination_before_deg=chosen.mean_before,
        inclination_after_deg=chosen.mean_after,
        orbit_before_deg=chosen.before,
        orbit_after_deg=chosen.after,
        n_orbits=chosen.n_orbits,
        # tangent k's z-coordinate is sample k + 2 tau: where the impact region starts
        orbit_flight_periods=flight_periods(chosen.starts + 2 * tau, impacts, period),
    )


def _both_means(
    grad: OrbitInclinations | None, poly: OrbitInclinations | None, contact: bool
) -> dict[str, float]:
    """Mean inclinations of both approaches (NaN where one has none or there is no contact)."""
    nan = float("nan")
    return dict(
        gradient_before_deg=grad.mean_before if contact and grad else nan,
        gradient_after_deg=grad.mean_after if contact and grad else nan,
        polynomial_before_deg=poly.mean_before if contact and poly else nan,
        polynomial_after_deg=poly.mean_after if contact and poly else nan,
    )


def geometric_estimate(
    accel: ArrayLike,
    fs_hz: float,
    *,
    method: str = "polynomial",
    delay: int | str = "period",
    dimension: int | str = "cao",
    calibration: GeometricCalibration | str | Path | None = "default",
    min_mode_ratio: float = 2.0,
    polynomial_degree: int = 1,
) -> GeometricResult:
    """Estimate the stiffness ratio of the impacted material from one acceleration record.

    Parameters
    ----------
    accel : array_like
        Acceleration of the mass (any gain, either polarity), at least three
        dominant periods long; a window of 16 natural periods (the dataset's)
        gives 15-20 orbits.
    fs_hz : float
        Sampling rate in Hz (reported frequency; impact detection's 10 ms
        minimum separation).
    method : {"polynomial", "gradient"}
        Inclinations fed to the calibration: polynomial fit (Table 1, default)
        or the mean tangent angle (eqs 9-10). Both are always computed.
    delay : int, "period" or "ami"
        Embedding delay: ``round(0.18 T)`` (default, see the module notes), the
        robust AMI rule, or a number of samples.
    dimension : int or "cao"
        Embedding dimension: Cao's rule (:func:`stiffnet.nlts.estimate_dimension`
        on at most 8192 samples) or a number; at least 3 are used since the
        method works in the x-z projection of ``(x, y, z)``.
    calibration : GeometricCalibration, path, "default" or None
        Map from inclinations to beta; None skips it (beta and class None).
    min_mode_ratio : float, optional
        Contact separation rule (:func:`~stiffnet.geometry.separation.separate_contact`).
    polynomial_degree : int, optional
        Degree of the curves of the polynomial approach.

    Returns
    -------
    GeometricResult

    Raises
    ------
    SignalError
        If the record is not a finite real 1-D signal, is constant, has no
        oscillation, or is shorter than three dominant periods.
    ConfigError
        For invalid options or an unreadable calibration file.
    """
    check_method(method)
    fs_hz = check_rate(fs_hz, "fs_hz", ConfigError)
    a = as_signal(accel, 32, "acceleration")
    cal = _resolve_calibration(calibration)
    if cal is not None and cal.method != method:
        raise ConfigError(
            f"calibration was fitted on {cal.method} inclinations, method is {method}"
        )
    s, period, win = _smoothed(a)
    y, tau, delay_rule, m_used, dim_rule = _embedded(s, period, delay, dimension)
    lag = tangent_lag(period)
    v = tangent_vectors(y[:, :3], lag)
    sep = separate_contact(tangent_magnitudes(v), min_mode_ratio=min_mode_ratio)
    # One impact per quarter period at most: both flanks of a soft spike are one impact.
    impacts = detect_impacts(s, fs=float(fs_hz), min_separation=max(1, int(0.25 * period)))
    grad, poly, contact, reason = _both_inclinations(
        y, v, sep, impacts, tau, lag, polynomial_degree
    )
    chosen: OrbitInclinations | None = (grad if method == "gradient" else poly) if contact else None
    pattern = impact_pattern(impacts, period) if contact else None
    if contact and not is_period1(pattern):
        reason = f"{reason}; {_period_n_caveat(pattern, cal)}"

    beta, cls, cal_orbit = _calibrated(chosen, cal, pattern)
    return GeometricResult(
        contact_detected=bool(contact),
        geometric_class=cls,
        geometric_beta=beta,
        **_chosen_inclinations(chosen, impacts, tau, period),
        **_both_means(grad, poly, contact),
        method=method,
        delay=tau,
        delay_rule=delay_rule,
        dimension=m_used,
        dimension_rule=dim_rule,
        period_samples=period,
        dominant_frequency_hz=float(fs_hz) / period,
        smoothing_window=win,
        tangent_lag=lag,
        impacts=impacts,
        threshold=sep.threshold if contact else float("inf"),
        contact_fraction=sep.contact_fraction if contact else 0.0,
        polarity=impact_polarity(s, impacts) if contact else 0,
        separation=sep,
        reason=reason,
        impact_pattern=pattern,
        calibration_orbit=cal_orbit,
    )
