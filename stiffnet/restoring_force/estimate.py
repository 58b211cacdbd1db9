"""The restoring-force (force-state mapping) estimate of beta, end to end.

Masri & Caughey's restoring-force surface (Worden & Tomlinson, *Nonlinearity in
Structural Dynamics*, ch. 7) for the impact oscillator: the accelerometer on the
mass reads the total restoring force per unit mass (docs/simulator.md; eqs 11-12),
so once displacement and velocity are known the force-displacement map *is* the
contact law. :func:`restoring_force_estimate` chains

1. the forcing frequency (:func:`~.reconstruct.forcing_frequency`, or given)
   and a segment of whole forcing periods that wraps around best;
2. frequency-domain integration to ``x_i``, ``v_i`` (:mod:`.reconstruct`);
3. the free-flight law ``-y = c v + k x`` with the table's motion at the forcing
   harmonics, and the contact split (:mod:`.free_flight`); ``k = (f_n / f_f)**2``
   when the natural frequency is given (near resonance the free decay and the
   forcing share a frequency and ``k`` is poorly determined by one record);
4. the contact law with dissipation and exponent on the samples around the
   impacts (:mod:`.contact_law`): ``beta = K / k``;
5. an interval by bootstrap over impacts (and, where the high-pass corner is the
   record's own, over the corners its contact law cannot exclude: :mod:`.corner_profile`),
   goodness of fit, and a refusal with a reason when there is no contact or the fit means
   nothing.

Polarity and gain: the record's polarity is chosen so that contact forces are
compressive (the spikes' side); every slope is a ratio within the same map, so
a gain cancels.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy import ndimage, optimize, stats

from stiffnet.errors import ConfigError, SignalError
from stiffnet.geometry.calibration import DEFAULT_CLASSES, NO_CONTACT, beta_class
from stiffnet.restoring_force.band import (
    band_passes_contacts,
    chain_free_reading,
    fitted_lowpass_refusal,
    kept_band,
    lowpass_refusal,
    smoothed_away_refusal,
    smoothed_contact_refusal,
)
from stiffnet.restoring_force.chain import (
    COVERAGE,
    SensorChain,
    deconvolve,
    fit_chain,
    identifiability,
    inverse_noise_sigma,
    sensor_from_mapping,
    settling_samples,
    sheet_fits_highpass,
)
from stiffnet.restoring_force.contact_law import (
    ContactLaw,
    equivalent_linear_band,
    exponent_matters,
    fit_contact_law,
    linear_contact_start,
    profile_contact_start,
)
from stiffnet.restoring_force.contact_poles import fit_contact_poles
from stiffnet.restoring_force.corner_profile import corner_readings
from stiffnet.restoring_force.free_flight import (
    CONTACT_SIGMAS,
    MIN_FLIGHT_SAMPLES,
    FreeFlightFit,
    fit_free_flight,
)
from stiffnet.restoring_force.hunt_crossley_law import (
    HuntCrossleyLaw,
    fit_hunt_crossley_law,
    hunt_crossley_shape,
)
from stiffnet.restoring_force.impact_onsets import ImpactOnsetLaw, fit_impact_onset_law
from stiffnet.restoring_force.kept_fits import kept
from stiffnet.restoring_force.reconstruct import (
    ALIAS_MIN_DAMPING,
    check_record,
    forcing_candidates,
    forcing_frequency,
    integrate_spectral,
    periodic_length,
)
from stiffnet.restoring_force.sensor import (
    RINGING_WINDOW,
    fit_highpass_corner,
    highpass_rule,
    resonance_rule,
    ringing_mode,
    undo_highpass,
    undo_resonance,
)
from stiffnet.restoring_force.soft_contact import SoftContactFit, fit_soft_contact, record_response
from stiffnet.restoring_force.staged_law import (
    StagedLaw,
    fit_staged_law,
    refit_at_ratio,
    staged_shape,
)

#: A fitted chain's inverse is kept unless the contact law explains this much less after it
#: (where a chain is always identified; where it is identified only when needed, no less).
R2_SLACK = 0.005
#: ``chain_fit_below_r2`` when the chain is identified only where needed: where the record
#: as recorded leaves the contact law explaining less than this. On a clean record the
#: chain changes nothing; and a fitted chain bends the map a contact-law discovery reads.
CHAIN_FIT_WHEN_NEEDED = 0.98
#: Shortest record, forcing periods.
MIN_PERIODS = 4.0
#: With f_n given, forcing lines below this fraction of it are not searched.
MIN_FORCING_RATIO = 0.25
#: Impacts needed for an estimate (and for the bootstrap).
MIN_IMPACTS = 3
#: Refuse when the contact law explains less of the contact force than this.
MIN_CONTACT_R2 = 0.5
#: High-pass corners profiled by the contact law (forcing frequencies: 0.1-5 Hz under a 10 Hz
#: forcing, what charge amplifiers offer) ...
HIGHPASS_GRID = np.geomspace(0.01, 0.5, 10)
#: ... and the share of the map's unexplained contact force the profiled corner may leave
#: (a real 2-5 Hz corner: 0.02-0.2; a spurious one on a record without: > 0.7).
HIGHPASS_PROFILE_GAIN = 0.5
#: Below this many samples per contact beta comes from the contact's oscillation
#: (:mod:`.contact_poles`) rather than the force-displacement map, whose displacement
#: inherits the quadrature error of spikes sampled with a few points (and of a damped
#: contact's onset jump); with more samples the map is the better of the two.
POLE_MAX_SAMPLES = 8
#: ... where the recursion explains at least this much of the in-contact samples (it is
#: exact for a Kelvin-Voigt contact: 0.9993-0.99998 on damped contacts at 2 % noise; a
#: low-pass near the contact's band adds poles, 0.91-0.9999) and the contacts last no
#: longer than the half period it gives (0.65-0.94 of it on damped contacts; 1.1-2.0
#: where a low-pass smears them).
POLE_MIN_R2 = 0.998
POLE_MAX_SPAN = 1.0
#: Free-flight damping ratios tried when the free flight's own ``c`` comes out negative
#: (see :func:`_profile_free_damping`): from none to twice the priors' 0.01-0.05.
FREE_DAMPING_GRID = (0.0, 0.015, 0.03, 0.05, 0.08)
#: ... where the contacts span at least this many samples: with fewer, the spikes'
#: quadrature errors dominate the contact law's residual, which then prefers a ``c``
#: that lets a strongly damped, soft law absorb them (beta read 2-10x low).
PROFILE_MIN_SAMPLES = 8
#: ... and where the contact law explains >= 90 % to begin with: a poorer law has other
#: errors (a mount resonance in the contact's band) that its fit would trade ``c`` for.
PROFILE_MIN_R2 = 0.9
#: Below this contact R2 the contact law is fitted again from an onset profiled over a grid.
SECOND_START_R2 = 0.95
#: Refuse when the contacts last longer than this many half periods of the fitted law.
MAX_DURATION_RATIO = 2.0
#: Refuse when the free-flight law explains less of the free restoring force than this.
MIN_FREE_R2 = 0.5
#: Systematic part of the interval (log beta): a floor, and a term growing with the contact
#: law's misfit; set on simulations with other seeds than bench_crosscheck's (90 % overall).
SYSTEMATIC_FLOOR = 0.02
SYSTEMATIC_PER_MISFIT = 4.0
#: ... and one over the samples per contact (an unseen anti-alias low-pass; set on
#: sensor chains drawn from the priors, seeds 11-12 of the development script).
SYSTEMATIC_PER_SAMPLE = 1.0
#: Bootstrap replicates over impacts.
N_BOOTSTRAP = 200
#: Why the joint fit of :mod:`.soft_contact` reads where no contact stands out ...
SOFT_UNSEEN = "too soft to stand out of the free-flight law"
#: ... and where, with no chain known, it leaves none of the record's harmonics
#: (:func:`~.band.chain_free_reading`).
SOFT_CHAIN_FREE = (
    f"{SOFT_UNSEEN}, with no harmonic of the forcing left beyond the record's noise (no "
    "low-pass needed)"
)
#: ... and behind a known low-pass below the stiffest contact, where the contact it reads
#: passes that low-pass (:func:`~.band.lowpass_refusal`).
SOFT_BEHIND_LOWPASS = (
    f"{SOFT_UNSEEN}, its harmonics showing contacts behind the known low-pass, which passes the "
    "contact read"
)


@dataclass(frozen=True)
class RestoringForceResult:
    """Result of :func:`restoring_force_estimate`.

    Attributes
    ----------
    ok : bool
        Whether beta was estimated; when False, `reason` says why.
    beta : float or None
        ``K / k``, the contact stiffness over the free-flight stiffness.
    beta_interval : tuple of float or None
        Bootstrap interval over impacts at `coverage`, spanning the profiled high-pass
        corners the record cannot exclude (:mod:`.corner_profile`) and a chain's other
        readings.
    restoring_force_class : str
        Class of `beta` by the configured edges, ``"no_contact"`` without contact,
        None when refused for another reason.
    contact_damping_ratio : float or None
        ``c_c / (2 sqrt(K))``: the contact's own damping ratio (``contact_damping``).
    exponent : float or None
        Contact exponent ``p`` (1 linear, 1.5 Hertz).
    free_damping_ratio : float
        ``xi = c / (2 sqrt(k))``.
    free_damping_fitted : float
        The free flight's own least-squares ``xi``, before a negative one is replaced by the
        profile over the contact law (``free_damping_ratio`` where none was): a high-pass
        corner undone off by ``delta`` leaves about ``delta f_h / (2 f_n)`` in it, sign
        included, which a campaign's corner reads (:mod:`serving.campaign_chain`).
    natural_frequency_hz : float
        ``f_f sqrt(k)`` (the given one when `stiffness_rule` is ``"given f_n"``).
    fitted_natural_frequency_hz : float or None
        ``f_n`` the free flight alone gives (a check on a given one).
    forcing_frequency_hz : float
    stiffness_rule : str
        ``"given f_n"`` or ``"fitted"``.
    highpass_hz : float
        Corner of the sensor chain's high-pass undone before integrating (0: none).
    resonance_hz : float or None
        Mounted resonance of the accelerometer divided out (None: no ringing seen).
    sensor : SensorChain or None
        The sensor chain undone before the map (:mod:`.chain`): fitted from the impacts or
        the data sheet's; None where no impact could be read.
    duration_ratio : float
        Median contact duration over the fitted law's half period ``pi / sqrt(K + k)``
        (~1 for a linear contact, less for a damped one's early release).
    n_impacts : int
    samples_per_contact : float
        Median samples in contact per impact (below ~4 the spike is barely resolved).
    free_r2, contact_r2 : float
        Goodness of fit of the free-flight and contact laws.
    polarity : int
        -1 if contact forces show as negative accelerations (stiffnet's sensor), +1 if positive.
    reason : str
        One line: what was estimated, or why not.
    displacement, force : numpy.ndarray
        The force-displacement map (gain units) for the figure.
    law : ContactLaw or None
        The fitted contact law (gain units).
    staged : StagedLaw or None
        The two-stage law that gives beta where a stage ratio was given (``stage_ratio``;
        :mod:`.staged_law`): beta is then its first-stage slope over ``k``.
    beyond_knee_interval : tuple of (float, float) or None
        Where a two-stage law's knee does not show on the map (`staged` not resolved): beta's
        interval had every impact been beyond the knee (the one slope over the ratio), which
        the map cannot exclude; `beta` and `beta_interval` read every impact short of it.
    hunt_crossley : HuntCrossleyLaw or None
        The law with a free ``delta v`` dissipation that gives beta where the model's law has
        one (``penetration_dissipation``; :mod:`.hunt_crossley_law`): beta is its elastic
        slope at first contact over ``k``.
    penetration_over_table : float or None
        The law's reference penetration ``d_r`` (the impacts' median peak penetration, where
        beta is the secant) over the table's displacement amplitude at the forcing frequency:
        a ratio of two lengths of the same map, so the record's gain cancels. Times the
        forcing amplitude ``a`` (model length units) it is ``d_r`` in the model's units.
    impact_onsets : ImpactOnsetLaw or None
        The contact law refitted with an onset per impact (:mod:`.impact_onsets`): the
        exponent where the reconstruction's level wanders between impacts. It reports only;
        beta is the law's above. None unless asked for (``impact_onsets=True``: the
        predictor's check).
    """

    ok: bool
    beta: float | None
    beta_interval: tuple[float, float] | None
    restoring_force_class: str | None
    contact_damping_ratio: float | None
    exponent: float | None
    free_damping_ratio: float
    natural_frequency_hz: float
    fitted_natural_frequency_hz: float | None
    forcing_frequency_hz: float
    stiffness_rule: str
    highpass_hz: float
    n_impacts: int
    samples_per_contact: float
    free_r2: float
    contact_r2: float
    polarity: int
    coverage: float
    reason: str
    displacement: np.ndarray = field(repr=False, default_factory=lambda: np.empty(0))
    velocity: np.ndarray = field(repr=False, default_factory=lambda: np.empty(0))
    force: np.ndarray = field(repr=False, default_factory=lambda: np.empty(0))
    free_stiffness: float = float("nan")
    resonance_hz: float | None = None
    duration_ratio: float = float("nan")
    law: ContactLaw | None = field(repr=False, default=None)
    sensor: SensorChain | None = None
    staged: StagedLaw | None = None
    beyond_knee_interval: tuple[float, float] | None = None
    hunt_crossley: HuntCrossleyLaw | None = None
    penetration_over_table: float | None = None
    reading_interval: tuple[float, float] | None = None
    impact_onsets: ImpactOnsetLaw | None = None
    free_damping_fitted: float = float("nan")

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready summary (no arrays)."""

        def num(v: float | None) -> float | None:
            return float(v) if v is not None and np.isfinite(v) else None

        return {
            "ok": self.ok,
            "beta": num(self.beta),
            "beta_interval": list(self.beta_interval) if self.beta_interval else None,
            "reading_interval": list(self.reading_interval) if self.reading_interval else None,
            "coverage": self.coverage,
            "restoring_force_class": self.restoring_force_class,
            "contact_damping_ratio": num(self.contact_damping_ratio),
            "exponent": num(self.exponent),
            "free_damping_ratio": num(self.free_damping_ratio),
            "natural_frequency_hz": num(self.natural_frequency_hz),
            "fitted_natural_frequency_hz": num(self.fitted_natural_frequency_hz),
            "forcing_frequency_hz": num(self.forcing_frequency_hz),
            "stiffness_rule": self.stiffness_rule,
            "highpass_hz": num(self.highpass_hz),
            "resonance_hz": num(self.resonance_hz),
            "duration_ratio": num(self.duration_ratio),
            "sensor": self.sensor.to_dict() if self.sensor is not None else None,
            "stage": _stage_dict(self.staged, self.beyond_knee_interval),
            "hunt_crossley": _hunt_crossley_dict(self.hunt_crossley),
            "n_impacts": self.n_impacts,
            "samples_per_contact": num(self.samples_per_contact),
            "free_r2": num(self.free_r2),
            "contact_r2": num(self.contact_r2),
            "polarity": self.polarity,
            "penetration_over_table": num(self.penetration_over_table),
            "impact_onsets": self.impact_onsets.to_dict() if self.impact_onsets else None,
            "reason": self.reason,
        }


def _stage_dict(
    staged: StagedLaw | None, beyond: tuple[float, float] | None
) -> dict[str, Any] | None:
    """The two-stage law's JSON fields (None without one)."""
    if staged is None:
        return None
    knee = staged.knee_fraction
    return {
        "ratio": float(staged.ratio),
        "resolved": bool(staged.resolved),
        "knee_fraction": float(knee) if np.isfinite(knee) else None,
        "r2": float(staged.r2),
        "beyond_knee_interval": [float(v) for v in beyond] if beyond else None,
    }


def _hunt_crossley_dict(law: HuntCrossleyLaw | None) -> dict[str, Any] | None:
    """The Hunt-Crossley law's JSON fields (None without one)."""
    if law is None:
        return None
    return {"onset": law.onset, "dissipation_share": law.dissipation_share, "r2": law.r2}


def _polarity(a: np.ndarray) -> int:
    """-1 if the record's extreme excursions (the contact spikes) point down, else +1."""
    med = float(np.median(a))
    lo, hi = np.percentile(a, [0.5, 99.5])
    return -1 if med - lo >= hi - med else 1


def impact_regions(contact: np.ndarray, margin: int) -> tuple[np.ndarray, int]:
    """Label each impact (a run of contact samples) with `margin` samples around it."""
    near = ndimage.binary_dilation(contact, iterations=margin) if margin > 0 else contact
    labels, n = ndimage.label(near)
    return labels, int(n)


def bootstrap_beta(
    law: ContactLaw,
    force: np.ndarray,
    disp: np.ndarray,
    vel: np.ndarray,
    labels: np.ndarray,
    n_impacts: int,
    stiffness: float,
    coverage: float,
    rng: np.random.Generator,
    n_boot: int = N_BOOTSTRAP,
) -> tuple[float, float]:
    """Interval of beta by resampling impacts: each impact's own secant stiffness, averaged.

    With the onset, damping and exponent of the global fit, each impact's
    stiffness is the least-squares ``K_j`` of ``F - c_c v = K_j g(d)`` on its
    samples in contact (``g(d) = d_r (d / d_r)**p``). Impacts are drawn with
    replacement and the mean of their ``K_j / k`` recomputed; the interval is
    the percentile interval, widened to contain the global estimate.
    """
    d = np.maximum(disp - law.onset, 0.0)
    g = law.reference_penetration * (d / law.reference_penetration) ** law.exponent
    return bootstrap_slope(g, force - law.damping * vel, (d > 0) & (force > 0), labels,
                           n_impacts, law.stiffness / stiffness, stiffness, coverage, rng,
                           n_boot)  # fmt: skip


def bootstrap_slope(
    g: np.ndarray,
    rhs: np.ndarray,
    inside: np.ndarray,
    labels: np.ndarray,
    n_impacts: int,
    beta: float,
    stiffness: float,
    coverage: float,
    rng: np.random.Generator,
    n_boot: int = N_BOOTSTRAP,
) -> tuple[float, float]:
    """:func:`bootstrap_beta` for any law shape: each impact's ``K_j`` of ``rhs = K_j g`` on
    its samples `inside` (the elastic force less the damping, the law's shape per unit
    ``K``), resampled over impacts around the global `beta`."""
    inside = inside & (labels > 0)
    idx = np.arange(1, n_impacts + 1)
    num = ndimage.sum(np.where(inside, g * rhs, 0.0), labels, idx)
    den = ndimage.sum(np.where(inside, g * g, 0.0), labels, idx)
    good = den > 0
    kj = num[good] / den[good] / stiffness
    if kj.size < 2:
        return beta, beta
    draws = rng.integers(0, kj.size, (n_boot, kj.size))
    # a weighted mean (by den) keeps the bootstrap centred on the global least-squares fit
    w = den[good]
    means = (kj[draws] * w[draws]).sum(axis=1) / w[draws].sum(axis=1)
    shift = beta - float(np.sum(kj * w) / np.sum(w))  # bias of the per-impact fits
    alpha = 0.5 * (1.0 - coverage)
    lo, hi = np.quantile(means + shift, [alpha, 1.0 - alpha])
    return float(min(lo, beta)), float(max(hi, beta))


def widen_interval(
    beta: float, lo: float, hi: float, contact_r2: float, samples_per_contact: float = np.inf
) -> tuple[float, float]:
    """Add the reconstruction's systematic error to the bootstrap interval (in log beta).

    The bootstrap over impacts sees the scatter between impacts, not the bias
    they share (integration of spikes sampled with a few points, a damped onset,
    an anti-alias low-pass that rounds the spikes): a floor of 2 %, ``4 (1 - R2)``
    of the contact law and ``1 / n`` for contacts of ``n`` samples are added in
    quadrature. The last is the sensor chain's: its low-pass sits at 0.15-0.45 fs
    (the priors), so the fewer samples a contact spans the closer the filter is to
    the contact's band, and the lower (by up to ~1/n in log beta on the priors'
    chains) the rounded spikes read beta, with the contact law still fitting well.
    """
    sys_hw = float(
        np.linalg.norm([SYSTEMATIC_FLOOR, SYSTEMATIC_PER_MISFIT * (1.0 - contact_r2),
                        SYSTEMATIC_PER_SAMPLE / max(samples_per_contact, 1.0)])
    )  # fmt: skip
    lo_hw = float(np.hypot(np.log(beta / lo), sys_hw)) if lo > 0 else np.inf
    hi_hw = float(np.hypot(np.log(hi / beta), sys_hw))
    return float(beta * np.exp(-lo_hw)), float(beta * np.exp(hi_hw))


def _refuse(reason: str, **kw: Any) -> RestoringForceResult:
    base: dict[str, Any] = dict(
        ok=False,
        beta=None,
        beta_interval=None,
        restoring_force_class=None,
        contact_damping_ratio=None,
        exponent=None,
        free_damping_ratio=float("nan"),
        natural_frequency_hz=float("nan"),
        fitted_natural_frequency_hz=None,
        forcing_frequency_hz=float("nan"),
        stiffness_rule="",
        highpass_hz=0.0,
        n_impacts=0,
        samples_per_contact=0.0,
        free_r2=float("nan"),
        contact_r2=float("nan"),
        polarity=0,
        coverage=0.9,
        reason=reason,
    )
    base.update(kw)
    return RestoringForceResult(**base)


@dataclass
class _Map:
    """One pass of the force-state map at a given high-pass correction."""

    fit: Any
    info: dict[str, Any]
    corner: float
    refusal: str = ""
    law: ContactLaw | None = None
    labels: np.ndarray | None = None
    n_impacts: int = 0
    spc: float = 0.0
    exponent: float | None = None
    source: np.ndarray | None = None
    #: A map of a chain's inverse (:func:`~.chain.deconvolve`): its short free runs join the
    #: contact (:data:`~.free_flight.MIN_FLIGHT_SAMPLES`)
    inverse: bool = False
    #: What the record of a chain's inverse keeps of the true acceleration
    #: (:func:`~.band.kept_band`): the contact law is fitted through it
    band: np.ndarray | None = None
    #: ``(1 - R2, beta)`` at each high-pass corner profiled where the corner is the record's
    #: own (:func:`_profiled_corner`; None where none was): the interval's corner term
    corner_profile: list[tuple[float, float]] | None = None


def _auto_map(
    y: np.ndarray,
    dtau: float,
    tau: np.ndarray,
    use: np.ndarray,
    period: float,
    k_given: float | None,
    exponent: float | None,
    profile_below_r2: float = np.inf,
    inverse: bool = False,
    band: np.ndarray | None = None,
) -> tuple[_Map, float]:
    """The map with the high-pass corner fitted (:mod:`.sensor`), and that corner.

    The plain map comes first: its free-flight scatter judges the corner
    (:func:`~.sensor.highpass_rule`), and a kept corner must not worsen the
    contact law's fit (on strongly damped contacts without any high-pass, the
    corner's terms absorb some free-flight misfit and pass the first tests).
    The corner is then profiled by the contact law (:func:`_profiled_corner`, about
    20 maps) only where the contact law explains less than `profile_below_r2`: the
    rule of a chain identified only where needed (:data:`CHAIN_FIT_WHEN_NEEDED`).
    `inverse`: `y` is a chain's inverse, `band` what it keeps (:class:`_Map`).

    The corner and its profile are a function of the inputs alone: kept where a caller reads
    the same records again (:func:`~.kept_fits.fits_kept`), the map then fitted once at the
    kept corner (the map :func:`_fit_map` gives at a corner is the map returned here).
    """
    args = (y, dtau, tau, use, period, k_given, exponent, profile_below_r2, inverse, band)
    fitted: list[_Map] = []

    def fit() -> tuple[float, list[tuple[float, float]] | None]:
        m, corner = _corner_map(*args)
        fitted.append(m)
        return corner, m.corner_profile

    corner, profile = kept("highpass corner", args, fit)
    if fitted:  # fitted now, not kept from before
        return fitted[0], corner
    m = _fit_map(y, dtau, tau, use, period, k_given, corner, exponent, inverse=inverse, band=band)
    return (m if profile is None else dataclasses.replace(m, corner_profile=profile)), corner


def _corner_map(
    y: np.ndarray,
    dtau: float,
    tau: np.ndarray,
    use: np.ndarray,
    period: float,
    k_given: float | None,
    exponent: float | None,
    profile_below_r2: float,
    inverse: bool,
    band: np.ndarray | None,
) -> tuple[_Map, float]:
    """:func:`_auto_map`, fitted (the plain map first, then the corner's)."""
    args = (y, dtau, tau, use, period, k_given)
    m = _fit_map(*args, 0.0, exponent, inverse=inverse, band=band)
    corner = highpass_rule(
        *fit_highpass_corner(y, dtau, tau, use, k_given, sigma_plain=m.fit.sigma)
    )
    if corner > 0:
        corrected = _fit_map(*args, corner, exponent, inverse=inverse, band=band)
        if _contact_r2(corrected) >= _contact_r2(m):
            m = corrected
        else:
            corner = 0.0
    if _contact_r2(m) >= profile_below_r2:
        return m, corner
    return _profiled_corner(m, corner, args, exponent)


def _profiled_corner(m: _Map, corner: float, args: tuple, exponent: float | None):
    """Rule: the high-pass corner that makes the contact force a function of the state.

    In a steady state the free-flight regression cannot see a high-pass (its impulse tails
    repeat with the forcing, and the table's harmonics absorb them: the start-up transient
    is what identifies it), yet a missed 2-5 Hz corner halves beta. The corner is profiled
    by the contact law's R2 over :data:`HIGHPASS_GRID` (forcing frequencies) and refined by
    a bounded search; the profiled corner replaces the map's where it leaves at most
    :data:`HIGHPASS_PROFILE_GAIN` of its unexplained contact force.
    """
    if m.law is None or m.labels is None:
        return m, corner
    seen: dict[float, _Map] = {}

    def at(c: float) -> _Map:  # a map is a function of its corner: the search's last point
        if c not in seen:  # is the corner it returns, mapped once
            seen[c] = _fit_map(*args, c, exponent, inverse=m.inverse, band=m.band)
        return seen[c]

    maps = {c: at(float(c)) for c in HIGHPASS_GRID}
    best = max(maps, key=lambda c: _contact_r2(maps[c]))
    i = int(np.flatnonzero(HIGHPASS_GRID == best)[0])
    lo, hi = HIGHPASS_GRID[max(i - 1, 0)], HIGHPASS_GRID[min(i + 1, HIGHPASS_GRID.size - 1)]
    sol = optimize.minimize_scalar(
        lambda u: -max(_contact_r2(at(float(np.exp(u)))), -1.0),
        bounds=(np.log(lo), np.log(hi)), method="bounded", options={"xatol": 0.02, "maxiter": 12},
    )  # fmt: skip
    c_best = float(np.exp(sol.x))
    profiled = at(c_best)
    if _contact_r2(maps[best]) > _contact_r2(profiled):
        c_best, profiled = float(best), maps[best]
    # every corner's reading and misfit: the interval spans those the record cannot exclude
    profile = [
        (1.0 - x.law.r2, x.law.stiffness / x.fit.stiffness)
        for x in (m, profiled, *maps.values()) if _readings([x])
    ]  # fmt: skip
    if 1.0 - _contact_r2(profiled) <= HIGHPASS_PROFILE_GAIN * (1.0 - _contact_r2(m)):
        m, corner = profiled, c_best
    return dataclasses.replace(m, corner_profile=profile), corner


def _in_contact(fit: FreeFlightFit, use: np.ndarray) -> np.ndarray:
    """The samples in contact: within the segment `use`, the free-flight law's residual force
    above :data:`CONTACT_SIGMAS` times its scatter."""
    return (fit.force > CONTACT_SIGMAS * fit.sigma) & use


def _contact_r2(m: _Map) -> float:
    """The contact law's R2 of a map (-inf when it has none)."""
    return m.law.r2 if m.law is not None else -np.inf


def _fit_map(
    y: np.ndarray,
    dtau: float,
    tau: np.ndarray,
    use: np.ndarray,
    period: float,
    k_given: float | None,
    corner: float,
    exponent: float | None,
    damping: float | None = None,
    inverse: bool = False,
    band: np.ndarray | None = None,
    contact: bool = True,
    lines_only: bool = False,
) -> _Map:
    """Integrate, fit the free flight and the contact law (see the module notes); `inverse`:
    `y` is a chain's inverse, `band` what it keeps (:class:`_Map`): the law is fitted
    through it. Without `contact`, the free flight alone (no impacts, no law): a map read
    only for its free flight. `lines_only`: the state integrated from the forcing lines
    alone (:func:`~.reconstruct.integrate_spectral`)."""
    source = y
    y = undo_highpass(y, dtau, corner)
    vel_i, disp_i = integrate_spectral(y, dtau, forcing_lines_only=lines_only)
    fit = fit_free_flight(y, vel_i, disp_i, tau, use, stiffness=k_given, damping=damping,
                          min_flight=MIN_FLIGHT_SAMPLES if inverse else 0)  # fmt: skip
    root_k = float(np.sqrt(max(fit.stiffness, 0.0)))
    info: dict[str, Any] = dict(
        free_r2=fit.r2,
        free_damping_ratio=fit.damping / (2 * root_k) if root_k > 0 else np.nan,
        natural_frequency_ratio=root_k,
        displacement=fit.displacement[use],
        velocity=fit.velocity[use],
        force=fit.force[use],
        free_stiffness=fit.stiffness,
    )
    if not contact:
        return _Map(fit, info, corner, source=source, inverse=inverse, band=band)
    if fit.stiffness <= 0:
        why = "the free-flight law has no positive stiffness: not an oscillator"
        return _Map(fit, info, corner, refusal=why, inverse=inverse, band=band)
    if fit.r2 < MIN_FREE_R2:
        why = f"the free-flight law explains {fit.r2:.0%} of the force (< 50 %)"
        return _Map(fit, info, corner, refusal=why, inverse=inverse, band=band)
    core = _in_contact(fit, use)
    labels, n_imp = impact_regions(core, max(2, int(0.03 * period)))
    labels[~use] = 0
    info["n_impacts"] = n_imp
    peak = float(fit.force[use].max()) / max(fit.sigma, 1e-300)
    if n_imp < MIN_IMPACTS:
        info["restoring_force_class"] = NO_CONTACT
        why = (
            f"no contact: {n_imp} excursion(s) of the restoring force beyond the linear "
            f"free-flight law ({MIN_IMPACTS} needed; largest {peak:.1f} sigma)"
        )
        return _Map(fit, info, corner, refusal=why, source=source, inverse=inverse, band=band)
    near = labels > 0
    spc = float(np.median(ndimage.sum(core, labels, np.arange(1, n_imp + 1))))
    info["samples_per_contact"] = spc
    kc0, e0, cc0 = linear_contact_start(fit.force, fit.displacement, fit.velocity, core)
    if not np.isfinite(kc0) or int(core.sum()) < 4:
        why = "the contact force does not grow with the displacement"
        return _Map(fit, info, corner, refusal=why, inverse=inverse, band=band)
    peaks = ndimage.maximum(fit.displacement - e0, labels, np.arange(1, n_imp + 1))
    dr = float(np.median(peaks)) if np.median(peaks) > 0 else float(np.std(fit.displacement))
    state = (fit.force, fit.displacement, fit.velocity, near)
    fixed = 1.0 if exponent is None else exponent
    law = fit_contact_law(*state, (kc0, e0, cc0), dr, fixed, band=band)
    # a second start where the first fit is poor: strongly damped contacts mislead it
    profiled = profile_contact_start(*state) if law.r2 < SECOND_START_R2 else (np.nan,)
    if np.isfinite(profiled[0]):
        other = fit_contact_law(*state, profiled, dr, fixed, band=band)
        law = other if other.sse < law.sse else law
    fitted_exponent = law.exponent
    if exponent is None:  # the exponent is reported; it sets beta only where it is significant
        free_law = fit_contact_law(*state, (law.stiffness, law.onset, law.damping), dr, band=band)
        fitted_exponent = free_law.exponent
        if exponent_matters(law, free_law):
            law = free_law
    # the contacts last about half a period of the contact's own oscillation (less when a
    # damped contact releases early, a little more when a filter smears them): a law far
    # stiffer than its contacts' duration allows is fitting something else
    duration = spc * dtau / (np.pi / np.sqrt(law.stiffness + fit.stiffness))
    info.update(law=law, contact_r2=law.r2, duration_ratio=duration)
    out = _Map(
        fit, info, corner, "", law, labels, n_imp, spc, fitted_exponent, source, inverse, band
    )
    if law.r2 < MIN_CONTACT_R2:
        out.refusal = (
            f"the contact law explains {law.r2:.0%} of the contact force (< 50 %): "
            "no meaningful fit"
        )
    elif duration > MAX_DURATION_RATIO:
        out.refusal = (
            f"the contacts last {duration:.1f}x the half period of the fitted contact law "
            f"(> {MAX_DURATION_RATIO:g}): its stiffness does not describe them"
        )
    return out


def _profile_free_damping(
    m: _Map,
    dtau: float,
    tau: np.ndarray,
    use: np.ndarray,
    period: float,
    k_given: float,
    exponent: float | None,
) -> _Map:
    """The map at the free damping that makes the contact force a function of the state.

    On a near-sinusoidal orbit the free flight alone cannot tell its damping
    force ``c v`` from the table's motion at the forcing frequency (the free R2
    moves by 1e-5 while ``c`` spans 0-0.1), and every wrong ``c`` leaves a
    sinusoid in phase with ``v`` in the reconstructed displacement: the contact
    branches of the map open into loops and beta moves by tens of per cent. The
    contact law tells them apart, so ``c`` is profiled over the priors' light
    damping and the map whose contact law fits best is kept.

    It runs where the free flight's own ``c`` is negative: a passive mass in free
    flight dissipates, so a negative ``c`` is the sign of that confusion (on the
    damped-contact records of a tuning seed, the over-estimates by 16-140 % all
    had one), where the contacts span :data:`PROFILE_MIN_SAMPLES` samples and where
    the contact law explains :data:`PROFILE_MIN_R2` of the contact force.
    """
    best, best_r2 = m, -np.inf
    for xi in FREE_DAMPING_GRID:
        other = _fit_map(m.source, dtau, tau, use, period, k_given, m.corner, exponent,
                         damping=2.0 * xi * np.sqrt(k_given), inverse=m.inverse,
                         band=m.band)  # fmt: skip
        if not other.refusal and _contact_r2(other) > best_r2:
            best, best_r2 = other, _contact_r2(other)
    return best


def _undo_chain(
    m: _Map,
    y: np.ndarray,
    fs_hz: float,
    ff: float,
    period: float,
    args: tuple,
    highpass_hz: float | str,
    exponent: float | None,
    sensor: SensorChain | None,
    beta_max: float = 100.0,
    chain_fit_below_r2: float = np.inf,
    rivals: bool = True,
    profile: bool = True,
    hunt_crossley: bool = False,
) -> tuple[_Map, SensorChain | None, float | None, str, list[float]]:
    """The map of the record with its sensor chain undone, the chain, the resonance divided
    out (Hz), a refusal where the chain's band does not carry the contact, and the beta the
    other readings give where a chain was fitted (the record as recorded, with the chain
    undone, with its low-pass at the ends of its interval): the interval spans them.

    The chain is the data sheet's (`sensor`) or fitted to the impacts of the plain map
    (:func:`~.chain.fit_chain`); a resonance or low-pass in the band is divided out within the
    band the record supports (:func:`~.chain.deconvolve`) and the map fitted again. Without
    impacts to fit, the post-impact ringing alone is divided out where it dominates (the
    older rule of :mod:`.sensor`). Without `rivals` the other readings are not mapped (none
    returned); without `profile` a fitted chain's unexcluded low-passes are not profiled.
    `hunt_crossley`: beta is read with a free ``delta v`` dissipation, and so are the other
    readings (:func:`_readings`).
    """
    beta_of_maps = functools.partial(_readings, hunt_crossley=hunt_crossley)
    use, k_given = args[3], args[5]
    natural = period / np.sqrt(m.fit.stiffness) if m.fit.stiffness > 0 else period
    ring = ringing_mode(m.fit.force, m.fit.contact, int(RINGING_WINDOW * natural))
    chain = sensor
    if chain is None and m.labels is not None and _contact_r2(m) < chain_fit_below_r2:
        fn_hz = fs_hz / natural
        core = _in_contact(m.fit, use)
        ring_hz = ring[0] * fs_hz / (2 * np.pi) if ring is not None and ring[2] > 0.5 else None
        hint = ff * float(np.sqrt(m.law.stiffness + m.fit.stiffness)) if m.law else None
        chain = fit_chain(m.fit.force, core, fs_hz, fn_hz, m.spc, ring_hz, m.corner * ff, hint,
                          m.fit.sigma, profile=profile)  # fmt: skip
    candidates = [(m, None)]  # (map, resonance divided out)
    mode = resonance_rule(ring, m.spc, natural) if sensor is None else None
    if mode is not None:  # the post-impact ringing dominates: divide that mode out
        m_ring = _remap(undo_resonance(y, *mode), args, highpass_hz, m.corner, exponent)
        candidates.insert(0, (m_ring, mode[0] * fs_hz / (2 * np.pi)))  # first: wins ties
    if chain is None or not chain.has_dynamics:
        best = max(candidates, key=lambda c: _contact_r2(c[0]))
        unseen = (
            _unexcluded_maps(chain, y, fs_hz, m, args, highpass_hz, exponent)
            + _highpass_end_maps(chain, y, fs_hz, ff, m, args, highpass_hz, exponent)
            if rivals
            else []
        )
        return best[0], chain, best[1], "", beta_of_maps([best[0], *unseen]) if unseen else []
    m2 = _inverse_map(chain, y, fs_hz, m, args, highpass_hz, m.corner, exponent)
    if chain.contact_hz is None and m2.law is not None and k_given is not None:
        contact_hz = ff * float(np.sqrt(m2.law.stiffness + m2.fit.stiffness))
        chain = dataclasses.replace(chain, contact_hz=contact_hz)
    refusal = identifiability(chain)
    below = bool(refusal) and chain.source != "fitted"
    if below:  # a known chain: its law is fitted through the band, which may still carry it
        refusal = _band_refusal(chain, m2, fs_hz / natural, args[3], args[1])
    no_contact = m2.info.get("restoring_force_class") == NO_CONTACT
    if no_contact and chain.source == "fitted":
        # a known chain's "no contact" is judged by the caller on the record's harmonics and,
        # where they show contacts, on the contact frequency the joint fit reads
        refusal = smoothed_away_refusal(chain.lowpass_hz, fs_hz / natural, beta_max)
    if chain.source != "fitted":
        # read below the low-pass: the interval spans this map's reading too (the free
        # damping profiled afterwards can move beta away from it)
        kept = beta_of_maps([m2]) if below and not refusal and rivals else []
        if rivals and not refusal:  # the corners' intervals, where the sheet gives them
            ends = _highpass_end_maps(chain, y, fs_hz, ff, m, args, highpass_hz, exponent)
            ends += _corner_maps(chain, y, fs_hz, m, args, m2, exponent)
            kept += beta_of_maps([m2, *ends]) if ends else []
        return m2, chain, chain.resonance_hz, refusal, kept
    # the chain that makes the contact force a function of the state: a fitted chain whose
    # inverse leaves the contact law worse than the record as recorded (or with only its
    # ringing divided out) is not the record's (it is still reported) and refuses nothing:
    # a contact law the library lacks also bends the pulse a chain would
    other = max(candidates, key=lambda c: _contact_r2(c[0]))
    # where the chain is identified only when needed (the predictor, the discovery) the
    # record's law already fits poorly, as an unseen law does too: there the inverse must
    # explain more, not about as much (a Hunt-Crossley pulse is fitted as a low-pass whose
    # inverse ties, and undoing it halves beta)
    slack = R2_SLACK if np.isinf(chain_fit_below_r2) else 0.0
    applied = _contact_r2(m2) >= _contact_r2(other[0]) - slack
    if applied and refusal:
        return m2, chain, chain.resonance_hz, refusal, []
    readings = (
        [c[0] for c in candidates]
        + [m2]
        + _corner_maps(chain, y, fs_hz, m, args, m2, exponent)
        + _unexcluded_maps(chain, y, fs_hz, m, args, highpass_hz, exponent)
        if rivals
        else []
    )
    if not applied:
        # a rejected chain refuses nothing, even with its low-pass below the contact: a
        # contact law the library lacks (Hunt-Crossley) is fitted as such a low-pass. The
        # interval spans the chain-undone reading instead, so a low-pass that was real
        # still leaves an interval that covers.
        chain = dataclasses.replace(chain, applied=False)
        return other[0], chain, other[1], "", beta_of_maps(readings)
    return m2, chain, chain.resonance_hz, refusal, beta_of_maps(readings)


def _forcing_lines_scale_map(m: _Map, args: tuple, damping: float | None) -> _Map | None:
    """The map that beta's scale is read from where the record's state is bent by the aliases
    of a damped contact's onset steps: the map again with its state integrated from the
    forcing lines alone and its law's shape held at the record's (None where `m` is kept).

    A damped contact's force steps at its onset, and a record sampled with no analog
    anti-alias filter (a simulator's, a chain applied digitally after the sampler) folds the
    step's harmonics between the forcing lines, where their integrals are a displacement the
    mass does not have (:func:`~.reconstruct.integrate_spectral`): the free-flight law
    ``-y = c v + k x + ...`` meets them as ``k / w**2`` times their acceleration, and the
    contact law's slope reads low. The lines' map is taken where the record's contact law is
    damped (:data:`~.reconstruct.ALIAS_MIN_DAMPING`), the lines' free flight scatters less (its
    robust sigma; a period-2 or 3 orbit has lines of its own between the forcing lines, which
    the free flight needs) and its contact law explains as much (within :data:`R2_SLACK`).

    Only the scale is the lines': the lines' state moves the impacts' onsets too, and a
    stiffening law read from it lost its curvature (a damped power law, exponent 2.06, read
    1.69 with an onset per impact; 1.99 from the record), so the lines' law is fitted at the
    record's exponent, and the law's shape (exponent, onsets, stage, damping ratio) stays the
    record's map's. `damping`: the free damping the record's map was profiled at (None where
    its free flight fitted its own)."""
    law = m.law
    if law is None or m.source is None or m.refusal:
        return None
    if not law.damping / (2.0 * np.sqrt(law.stiffness)) >= ALIAS_MIN_DAMPING:
        return None
    y, dtau, tau, use, period, k_given = args
    lines = _fit_map(m.source, dtau, tau, use, period, k_given, m.corner, law.exponent,
                     damping=damping, inverse=m.inverse, band=m.band, lines_only=True)  # fmt: skip
    if lines.refusal or lines.law is None or not lines.fit.sigma < m.fit.sigma:
        return None
    if _contact_r2(lines) < _contact_r2(m) - R2_SLACK:  # a free flight bought with the contact
        return None
    return lines


def _band_refusal(chain: SensorChain, m2: _Map, natural_hz: float, use, dtau) -> str:
    """The refusal of a known chain whose low-pass sits below the contact's frequency
    (:func:`~.band.lowpass_refusal`), judged at the low end of beta's interval from the map of
    its inverse."""
    if m2.law is None or m2.refusal:
        return identifiability(chain)
    _, (lo, _), _, _ = _beta_of_map(m2, use, dtau, COVERAGE, 0)
    return lowpass_refusal(chain, natural_hz, float(lo))


def _corner_maps(chain: SensorChain, y, fs_hz, m: _Map, args, read: _Map, exponent) -> list:
    """The maps with the low-pass at the ends of its interval (its uncertainty: a fitted
    chain's, or a campaign's profiled corner given as a data sheet's ``lowpass_low_hz`` /
    ``lowpass_high_hz``), the high-pass held at the corner of the map `read` through the
    chain: profiled again at each end, the corner is tuned until the contact law fits and
    takes part of the low-pass's effect back (as in :func:`_unexcluded_maps`); held, an end
    is one map rather than a profile's twenty (:func:`_profiled_corner`)."""
    ends = chain.intervals.get("lowpass_hz") if chain.lowpass_hz else None
    if not ends or not all(np.isfinite(ends)):
        return []
    return [
        _inverse_map(dataclasses.replace(chain, lowpass_hz=float(f)), y, fs_hz, m, args,
                     read.corner, read.corner, exponent)
        for f in sorted({float(f) for f in ends}) if 0 < f < 0.5 * fs_hz and f != chain.lowpass_hz
    ]  # fmt: skip


def _highpass_end_maps(chain, y, fs_hz, ff, m: _Map, args, highpass_hz, exponent) -> list:
    """The maps with a known chain's high-pass corner at the ends of its interval (a
    campaign's profiled corner: the corners its contact laws cannot tell apart), the chain's
    resonance and low-pass divided out as in the reading; none where the sheet gives no
    interval or the corner is the record's own (``"auto"``)."""
    ends = chain.intervals.get("highpass_hz") if chain is not None else None
    if not ends or chain.source == "fitted" or highpass_hz == "auto":
        return []
    out = []
    for f in {float(f) for f in ends if f != chain.highpass_hz}:
        at = dataclasses.replace(chain, highpass_hz=f)
        out.append(_inverse_map(at, y, fs_hz, m, args, f, f / ff, exponent) if at.has_dynamics
                   else _remap(y, args, f, f / ff, exponent))  # fmt: skip
    return out


def _unexcluded_maps(chain, y, fs_hz, m: _Map, args, highpass_hz, exponent) -> list:
    """The maps through each low-pass the impacts cannot exclude (a fitted chain's
    ``lowpass_not_excluded``): a low-pass the fit does not see may still bend beta. The
    high-pass stays at the record's corner: profiled again, it is tuned until the contact law
    fits and takes the low-pass's effect back."""
    if chain is None or chain.source != "fitted":
        return []
    return [
        _inverse_map(dataclasses.replace(chain, lowpass_hz=f, lowpass_order=o), y, fs_hz, m,
                     args, m.corner, m.corner, exponent, inverse=False)
        for o, f in chain.lowpass_not_excluded if 0 < f < 0.5 * fs_hz
    ]  # fmt: skip


def _readings(maps: list[_Map], hunt_crossley: bool = False) -> list[float]:
    """Beta of each readable map (no refusal, a contact law explaining half the force), in
    the sense of the reading they stand beside: with `hunt_crossley`, the elastic slope at
    first contact of the law with a free ``delta v`` dissipation (:mod:`.hunt_crossley_law`)
    wherever the map's law is linear, as :func:`_hunt_crossley_beta` reads it. The library's
    Kelvin-Voigt slope of a Hunt-Crossley contact reads 5-65 % high, so an interval spanning
    it beside a Hunt-Crossley reading spans the other law, not the chain's uncertainty."""
    out = []
    for x in maps:
        if x.law is None or x.refusal or x.law.r2 < MIN_CONTACT_R2 or not x.fit.stiffness > 0:
            continue
        stiffness = x.law.stiffness
        if hunt_crossley and x.law.exponent == 1.0:
            f = x.fit
            stiffness = fit_hunt_crossley_law(f.force, f.displacement, f.velocity, x.labels > 0,
                                              x.law).stiffness  # fmt: skip
        out.append(float(stiffness / x.fit.stiffness))
    return out


def _inverse_map(
    chain: SensorChain,
    y,
    fs_hz,
    m: _Map,
    args,
    highpass_hz,
    corner,
    exponent,
    inverse: bool = True,
) -> _Map:
    """The map of `y` with `chain` divided out (:func:`~.chain.deconvolve`), its contact law
    fitted through what the inverse keeps (:func:`~.band.kept_band`) where the chain is known
    (a data sheet, a campaign's pooled chain); `inverse` as :class:`_Map` (its short free runs
    join the contact)."""
    # a fitted chain is judged by the contact law it leaves (R2 against the record as
    # recorded, R2_SLACK): a law fitted through its band explains more whether the chain is
    # right or not, so a fitted chain's map keeps the plain fit
    sigma = inverse_noise_sigma(y, fs_hz, chain, m.fit.sigma)
    band = kept_band(y, fs_hz, chain, sigma) if chain.source != "fitted" else None
    flat = deconvolve(y, fs_hz, chain, sigma)
    return _remap(flat, args, highpass_hz, corner, exponent, inverse=inverse, band=band)


def _remap(y, args, highpass_hz, corner, exponent, inverse: bool = False, band=None) -> _Map:
    """The map of `y` with the high-pass fitted again (``"auto"``) or at `corner`; `inverse`:
    `y` is a chain's inverse, `band` what it keeps (:class:`_Map`)."""
    _, dtau, tau, use, period, k_given = args
    if highpass_hz == "auto":
        return _auto_map(y, dtau, tau, use, period, k_given, exponent, inverse=inverse,
                         band=band)[0]  # fmt: skip
    return _fit_map(y, dtau, tau, use, period, k_given, corner, exponent, inverse=inverse,
                    band=band)  # fmt: skip


def restoring_force_estimate(
    accel: ArrayLike,
    fs_hz: float,
    *,
    natural_frequency_hz: float | None = None,
    forcing_frequency_hz: float | None = None,
    exponent: float | None = None,
    classes=DEFAULT_CLASSES,
    coverage: float = 0.9,
    seed: int = 0,
    max_periods: float | None = None,
    highpass_hz: float | str = "auto",
    sensor: SensorChain | dict | None = None,
    sensor_fitted: bool = False,
    chain_fit_below_r2: float = np.inf,
    profile_highpass_below_r2: float | None = None,
    interval: bool = True,
    stage_ratio: float | tuple[float, float] | None = None,
    penetration_dissipation: bool = False,
    impact_onsets: bool = False,
    chain_profile: bool = False,
) -> RestoringForceResult:
    """Estimate beta from one acceleration record by the restoring-force method.

    Parameters
    ----------
    accel : array_like
        Acceleration of the mass (any gain, either polarity), at least four
        forcing periods; 16 or more give a usable interval.
    fs_hz : float
        Sampling rate, Hz.
    natural_frequency_hz : float, optional
        Natural frequency of the free mass; fixes ``k = (f_n / f_f)**2``.
        None fits ``k`` from the free flight (poorly determined near resonance).
    forcing_frequency_hz : float, optional
        Forcing frequency (the manifest's); estimated from the spectrum when None.
    exponent : float, optional
        Fix the contact exponent (1 for a linear restraint); fitted when None.
    classes : sequence of (name, low, high)
        Class edges in beta (the shipped ones: ``geometry.calibration.DEFAULT_CLASSES``).
    coverage : float
        Nominal coverage of the bootstrap interval.
    seed : int
        Seed of the bootstrap.
    max_periods : float, optional
        Analyse at most this many forcing periods (the middle of the record).
    highpass_hz : float or "auto"
        Corner of a first-order high-pass in the sensor chain (charge amplifier),
        undone before integrating. ``"auto"`` (default) fits it jointly with the
        free-flight law (:mod:`~stiffnet.restoring_force.sensor`; a corner
        within two standard errors of zero counts as none); a number gives it
        (the data sheet's), 0 assumes none.
    sensor : SensorChain or dict, optional
        The sensor chain from its data sheet (``resonance_hz``, ``resonance_damping``,
        ``lowpass_hz``, ``lowpass_order``, ``highpass_hz``; a stage left out is none): it is
        undone as given and nothing is fitted, except a ``highpass_hz`` of ``"auto"`` (a
        campaign's pooled chain), fitted as `highpass_hz` ``"auto"`` fits it and reported
        in the chain. The corner's interval (``highpass_low_hz``, ``highpass_high_hz``: a
        campaign's profiled corner) puts beta's readings at its ends into beta's interval,
        as do the low-pass corner's (``lowpass_low_hz``, ``lowpass_high_hz``).
        None (default) identifies the chain from the impacts
        (:func:`~stiffnet.restoring_force.chain.fit_chain`) and undoes it.
    sensor_fitted : bool
        `sensor` was fitted to recordings, not given by the user (a campaign's pooled chain,
        ``diagnose``'s shared chain, a log's held chain): read as a data sheet, its inverse
        weighted as a fitted chain's
        (:func:`~stiffnet.restoring_force.chain.inverse_noise_sigma`). False (default): the
        user's data sheet.
    chain_fit_below_r2 : float, optional
        Identify the chain only where the record as recorded leaves the contact law
        explaining less than this (R2; default: always). A chain that distorts the
        contact shows as a law that no longer fits, and the identification costs
        0.1-2 s against the estimate's ~10 ms: the predictor fits it only when needed.
        The same gate holds for profiling the high-pass corner by the contact law
        (``"auto"``; ~20 maps, ~0.2 s) unless `profile_highpass_below_r2` is given.
    profile_highpass_below_r2 : float, optional
        Profile the high-pass corner by the contact law only where the record's law
        explains less than this (default: `chain_fit_below_r2`). ``-inf`` never profiles:
        what a contact-law discovery needs, since the profile tunes the corner until the
        library's law fits and so bends a law the library lacks.
    interval : bool
        False: the map, its contact law and beta without beta's interval (``beta_interval``
        is ``(nan, nan)``): no bootstrap, and a fitted chain's other readings (its low-pass
        at the ends of its interval, the low-passes the impacts cannot exclude) are neither
        profiled nor mapped, unless the record's start-up is read through them
        (:func:`_estimate_settled`). What a caller that reads only the map needs (the
        contact-law discovery): the same map and the same choice of chain, for less CPU
        where a chain is fitted.
    stage_ratio : float or (float, float), optional
        The stage ratio of a model's learned two-stage law (its ``knee_ratio``, a value or
        its prior range): beta is then that law's first-stage slope over ``k``, fitted with
        the ratio held and the knee free (:mod:`.staged_law`); a range's ends join the
        interval. None (default): the library's law.
    penetration_dissipation : bool
        The model's learned law has a dissipation growing with penetration (a Hunt-Crossley
        ``delta v`` term): beta is then the elastic slope at first contact of the law with
        that term fitted free (:mod:`.hunt_crossley_law`), where the map's leading term is
        linear (its exponent not significant, as the model's law); a map that needs a power
        law keeps the library's reading. A `stage_ratio` takes precedence. False (default):
        the library's law.
    impact_onsets : bool
        Also refit the contact law with an onset per impact (:mod:`.impact_onsets`), reported
        beside beta (``impact_onsets``) for the alarm's exponent rules; beta and its interval
        do not change. Six small fits per record: only the predictor's check asks for it.
    chain_profile : bool
        Without an `interval`, still profile a fitted chain's low-passes the impacts cannot
        exclude (``lowpass_not_excluded``), so the chain reported is the one an estimate with
        an interval reports; its other readings are not mapped. What a caller that keeps only
        the fitted chain needs (a campaign's chain fitted regardless of the gate). False
        (default): profiled without an interval only where the record's start-up is read
        through them (:func:`_estimate_settled`).

    Returns
    -------
    RestoringForceResult
        ``ok`` False with a ``reason`` when there is no contact or no meaningful fit.

    Raises
    ------
    ConfigError
        For invalid options.
    SignalError
        If the record is not a finite 1-D signal with an oscillation, or too short.
    """
    sensor, highpass_hz = _checked_options(fs_hz, natural_frequency_hz, forcing_frequency_hz,
                                           coverage, sensor, highpass_hz)  # fmt: skip
    if sensor is not None and sensor_fitted:
        sensor = dataclasses.replace(sensor, fitted_sheet=True)
    a, lines = _record_and_lines(accel, fs_hz, natural_frequency_hz, forcing_frequency_hz,
                                 max_periods)  # fmt: skip
    options = dict(natural_frequency_hz=natural_frequency_hz, exponent=exponent,
                   classes=classes, coverage=coverage, seed=seed, max_periods=max_periods,
                   highpass_hz=highpass_hz, sensor=sensor,
                   chain_fit_below_r2=chain_fit_below_r2,
                   profile_highpass_below_r2=chain_fit_below_r2
                   if profile_highpass_below_r2 is None else profile_highpass_below_r2,
                   interval=interval, stage_ratio=stage_ratio,
                   penetration_dissipation=penetration_dissipation,
                   impact_onsets=impact_onsets, chain_profile=chain_profile)  # fmt: skip
    results = []
    for i, ff in enumerate(lines):
        try:
            results.append(_estimate_settled(a, fs_hz, ff, options))
        except SignalError:
            if i == 0 and len(lines) == 1:
                raise
    if not results:
        raise SignalError("no forcing line leaves four forcing periods in the record")
    return max(results, key=lambda r: r.free_r2 if np.isfinite(r.free_r2) else -np.inf)


def _estimate_settled(a: np.ndarray, fs_hz: float, ff: float, options: dict):
    """:func:`_estimate_at`, read again from where the chain's low-pass has settled.

    A lab chain starts from rest with its logger: until its low-pass has settled
    (:func:`~.chain.settling_samples`) the record is no filtered copy of the motion, and
    those samples bias the fitted high-pass corner low (the inverse's integral starts
    there). Where a low-pass is identified, given or not excluded, and a high-pass corner was
    fitted, the record is read again without them; records with no low-pass or no high-pass,
    and records read from their middle (`max_periods`), are read as they are.
    """
    most = options["max_periods"]
    if options["highpass_hz"] != "auto" or (most is not None and a.size > most * fs_hz / ff):
        # a corner given, or a record cut from its middle: no start-up in it, and the chain's
        # unexcluded low-passes are read only for the interval
        return _estimate_at(a, fs_hz, ff, **options)
    # the settling reads the chain's unexcluded low-passes: profiled even without an interval
    options = {**options, "chain_profile": True}
    first = _estimate_at(a, fs_hz, ff, **options)
    skip = settling_samples(first.sensor, fs_hz) if first.highpass_hz > 0 else 0
    if skip == 0:
        return first
    try:
        return _estimate_at(a[skip:], fs_hz, ff, **options)
    except SignalError:  # the record is too short without them: read it whole
        return first


def _checked_options(
    fs_hz, natural_frequency_hz, forcing_frequency_hz, coverage, sensor, highpass_hz
) -> tuple[SensorChain | None, float | str]:
    """Rule: the options checked (a :class:`ConfigError` naming the bad one), the data sheet
    as a chain, and the high-pass to undo (the data sheet's where one is given)."""
    for name, value in (("fs_hz", fs_hz), ("natural_frequency_hz", natural_frequency_hz),
                        ("forcing_frequency_hz", forcing_frequency_hz)):  # fmt: skip
        if value is None and name != "fs_hz":
            continue
        if not (isinstance(value, int | float | np.number) and np.isfinite(value) and value > 0):
            raise ConfigError(f"{name} must be a positive number, got {value!r}")
    if not 0 < coverage < 1:
        raise ConfigError(f"coverage must be in (0, 1), got {coverage!r}")
    fitted = isinstance(sensor, dict) and sheet_fits_highpass(sensor)
    if isinstance(sensor, dict):
        try:
            sensor = sensor_from_mapping(sensor, fs_hz)
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
    if sensor is not None:  # the data sheet's high-pass is the one undone, unless it asks
        highpass_hz = "auto" if fitted else float(sensor.highpass_hz)  # for the record's
    return sensor, highpass_hz


def _record_and_lines(
    accel: ArrayLike,
    fs_hz: float,
    natural_frequency_hz: float | None,
    forcing_frequency_hz: float | None,
    max_periods: float | None,
) -> tuple[np.ndarray, list[float]]:
    """The record (cropped to about `max_periods` forcing periods around its middle) and the
    forcing lines to try: the given one, else the spectrum's rival lines (period-n orbits;
    the free-flight law picks among them)."""
    from stiffnet.nlts._validate import as_signal

    a = as_signal(accel, 32, "acceleration")
    if float(np.std(a)) == 0.0:
        raise SignalError("acceleration is constant")
    # a forcing line below a quarter of f_n is no rig's (the priors: 0.8-1.2 f_n); below it
    # a charge amplifier's start-up transient can top the velocity spectrum
    min_hz = MIN_FORCING_RATIO * natural_frequency_hz if natural_frequency_hz else None
    if max_periods is not None:  # crop first: the spectrum of a long record costs most
        mid = a[max(0, a.size // 2 - 32768) : a.size // 2 + 32768]
        coarse = (
            fs_hz / forcing_frequency_hz
            if forcing_frequency_hz
            else max(forcing_candidates(mid, fs_hz, min_hz))
        )
        keep = int(1.1 * max_periods * coarse)
        if a.size > keep:
            a = a[(a.size - keep) // 2 :][:keep]
    if forcing_frequency_hz:
        return a, [float(forcing_frequency_hz)]
    return a, [forcing_frequency(a, fs_hz, coarse=c) for c in forcing_candidates(a, fs_hz, min_hz)]


def _estimate_at(
    a: np.ndarray,
    fs_hz: float,
    ff: float,
    *,
    natural_frequency_hz: float | None,
    exponent: float | None,
    classes,
    coverage: float,
    seed: int,
    max_periods: float | None,
    highpass_hz: float | str,
    sensor: SensorChain | None,
    chain_fit_below_r2: float,
    profile_highpass_below_r2: float,
    interval: bool = True,
    chain_profile: bool = False,
    stage_ratio: float | tuple[float, float] | None = None,
    penetration_dissipation: bool = False,
    impact_onsets: bool = False,
) -> RestoringForceResult:
    """:func:`restoring_force_estimate` at a given forcing frequency ``ff`` (Hz); without an
    `interval`, a fitted chain's unexcluded low-passes are profiled only with
    `chain_profile`."""
    if not ff < 0.5 * fs_hz:
        raise ConfigError(f"forcing frequency {ff:.3g} Hz is not below Nyquist ({fs_hz / 2:g} Hz)")
    args, polarity = _periodic_record(a, fs_hz, ff, natural_frequency_hz, max_periods)
    y, dtau, tau, use, period, k_given = args
    if highpass_hz == "auto":
        m, corner = _auto_map(
            y, dtau, tau, use, period, k_given, exponent, profile_highpass_below_r2
        )
    else:
        if not (
            isinstance(highpass_hz, int | float) and np.isfinite(highpass_hz) and highpass_hz >= 0
        ):
            raise ConfigError(f"highpass_hz must be a number >= 0 or 'auto', got {highpass_hz!r}")
        corner = float(highpass_hz) / ff
        # behind a known chain that is divided out, the record as recorded gives the inverse
        # only its free flight (scatter, stiffness, ringing): its contact law is never read
        undone = sensor is not None and sensor.source != "fitted" and sensor.has_dynamics
        m = _fit_map(*args, corner, exponent, contact=not undone)
    beta_max = max(float(hi) for _, _, hi in classes)
    m, chain, resonance, refusal, rivals = _undo_chain(
        m, y, fs_hz, ff, period, args, highpass_hz, exponent, sensor, beta_max,
        chain_fit_below_r2, rivals=interval, profile=interval or chain_profile,
        hunt_crossley=penetration_dissipation and stage_ratio is None,
    )  # fmt: skip
    corner, corner_profile = m.corner, m.corner_profile
    own_damping = float(m.info.get("free_damping_ratio", np.nan))
    free_damping = None
    if (k_given is not None and m.law is not None and m.info["free_damping_ratio"] < 0
            and m.spc >= PROFILE_MIN_SAMPLES and m.law.r2 >= PROFILE_MIN_R2):  # fmt: skip
        profiled = _profile_free_damping(m, dtau, tau, use, period, k_given, exponent)
        free_damping = profiled.fit.damping if profiled is not m else None
        m = profiled
    m.info["free_damping_fitted"] = own_damping
    fit, info = m.fit, m.info
    if chain is not None and chain.applied and highpass_hz == "auto":
        # the corner of the map that was read: a data sheet's "auto" is the record's own,
        # and a fitted chain's was fitted on the record as recorded, before its resonance
        # or low-pass was undone (a 237 Hz mount's ring read as a 3-4 Hz corner for 1 Hz)
        chain = dataclasses.replace(chain, highpass_hz=m.corner * ff)
    info["resonance_hz"] = resonance
    info["sensor"] = chain
    info.update(
        forcing_frequency_hz=ff,
        polarity=polarity,
        coverage=coverage,
        stiffness_rule="given f_n" if k_given is not None else "fitted",
        highpass_hz=corner * ff,
        natural_frequency_hz=ff * info.pop("natural_frequency_ratio"),
    )
    beta_min = _least_beta(classes)
    known = chain if chain is not None and chain.source != "fitted" else None
    lowpass = None if known is None else (known.lowpass_hz or np.inf)
    carried = band_passes_contacts(lowpass, info["natural_frequency_hz"], beta_max)
    soft_reading = functools.partial(_soft_reading, m, args, info, classes, coverage, seed, rivals)
    if not refusal and info.get("restoring_force_class") == NO_CONTACT:
        # no impact stands out: unless a low-pass smoothed them away (their harmonics remain)
        fn_hz = info["natural_frequency_hz"]
        refusal = smoothed_contact_refusal(
            y, period, fs_hz, fn_hz, beta_min, beta_max, lowpass,
        )  # fmt: skip
        if refusal and (carried or known is None):
            # contacts the band carries, too soft to stand out; with no chain known, only
            # where the joint law needs no chain to explain the record
            soft = soft_reading() if carried else soft_reading(SOFT_CHAIN_FREE, chain_free=True)
            if soft is not None:
                return soft
        elif refusal:
            # a known low-pass below the stiffest contact: the joint fit, forward through the
            # chain, reads the record's own contact, which the low-pass may still carry
            soft = soft_reading(SOFT_BEHIND_LOWPASS)
            if soft is not None:
                at = dataclasses.replace(known, contact_hz=fn_hz * float(np.sqrt(1.0 + soft.beta)))
                refusal = lowpass_refusal(at, fn_hz, float(soft.beta_interval[0]))
                if not refusal:
                    return soft
        elif not carried and known is not None:  # no harmonics: no contact, unless smoothed
            refusal = smoothed_away_refusal(lowpass, fn_hz, beta_max)
    if refusal:  # the sensor's band: neither a class nor "no contact" can be read
        return _refuse(refusal, **{**info, "restoring_force_class": None})
    if m.refusal:
        law_beta = m.law.stiffness / m.fit.stiffness if m.law is not None else None
        why = _map_below_classes(law_beta, beta_min, carried)
        soft = soft_reading(why) if why else None
        return soft if soft is not None else _refuse(m.refusal, **info)
    staged, poles, beyond, hc, lines_note = None, None, None, None, ""
    if stage_ratio is not None:
        beta, (lo, hi), damping_ratio, staged, beyond = _staged_beta(m, stage_ratio, coverage,
                                                                     seed, interval)  # fmt: skip
    elif penetration_dissipation and m.law.exponent == 1.0:
        # a map that needs a power law shows a term the model's law lacks: the library's
        # reading then, and the contact_law check judges the exponent
        beta, (lo, hi), damping_ratio, hc = _hunt_crossley_beta(m, coverage, seed, interval)
    else:
        beta, (lo, hi), damping_ratio, poles = _beta_of_map(m, use, dtau, coverage, seed,
                                                            interval)  # fmt: skip
        lines = _forcing_lines_scale_map(m, args, free_damping) if poles is None else None
        if lines is not None:
            beta_l, (lo_l, hi_l), _, poles_l = _beta_of_map(lines, use, dtau, coverage, seed,
                                                            interval)  # fmt: skip
            if poles_l is None:
                # the scatter does not prove which lines are the mass's (behind a low-pass at
                # the contact's frequency the two readings part by up to a half): the
                # interval spans the record's own reading's too
                lines_note = (f"; beta from the state of the forcing lines alone (its free "
                              f"flight scatters {1 - lines.fit.sigma / fit.sigma:.0%} less; "
                              f"the record's own state reads {beta:.3g})")  # fmt: skip
                beta, lo, hi = beta_l, min(lo, lo_l), max(hi, hi_l)
    if stage_ratio is None and hc is None:
        why = _map_below_classes(beta, beta_min, carried)
        soft = soft_reading(why) if why else None
        if soft is not None:
            return soft
    if interval and corner_profile and stage_ratio is None and hc is None and poles is None:
        # the record's own high-pass corner: the interval is the union of the intervals at
        # every corner its contact law cannot exclude, each as wide (in log beta) as the
        # read corner's (the bootstrap and systematic terms hold the corner fixed)
        at = corner_readings(corner_profile, m.n_impacts, coverage)
        lo = min([lo, *(b * lo / beta for b in at)])
        hi = max([hi, *(b * hi / beta for b in at)])
    if rivals:  # a fitted chain's uncertainty: every reading it leaves open is in the interval
        lo, hi = min(lo, *rivals), max(hi, *rivals)
    # where the reading's betas reach a contact above the low-pass the fit chose for it
    lowpass_refused = fitted_lowpass_refusal(info["sensor"], info["natural_frequency_hz"], hi)
    if interval and lowpass_refused:
        return _refuse(lowpass_refused, **{**info, "restoring_force_class": None})
    law_note, reading = "", None
    if interval and stage_ratio is None and hc is None and poles is None and m.law.exponent > 1:
        # a stiffening law's beta is a convention (the secant at the impacts' median peak
        # penetration): the interval spans the linear springs the law stands for there
        low, high = equivalent_linear_band(m.law.exponent)
        reading = (lo, hi)
        lo, hi = min(lo, beta * low), max(hi, beta * high)
        law_note = (f"; a power law (exponent {m.law.exponent:.2f}): beta is its secant "
                    f"stiffness at the impacts' median peak penetration, the interval spans "
                    f"the linear springs of its energy (x{low:.2f}) to its slope (x{high:.2f}) "
                    "there")  # fmt: skip
    fitted_fn = None if k_given is not None else ff * float(np.sqrt(fit.stiffness))
    cls = str(beta_class(np.array([beta]), classes)[0])
    law, n_imp, spc = m.law, m.n_impacts, m.spc
    onsets = None
    if impact_onsets:
        core = _in_contact(fit, use)
        maps = (fit.force, fit.displacement, fit.velocity, m.labels, core)
        # the map's own law (not a model's two-stage one): kept where the record is read again
        onsets = kept("impact onsets", (*maps, *dataclasses.astuple(law)),
                      lambda: fit_impact_onset_law(*maps, law))  # fmt: skip
    return RestoringForceResult(
        ok=True,
        beta=float(beta),
        beta_interval=(lo, hi),
        reading_interval=reading,
        restoring_force_class=cls,
        contact_damping_ratio=damping_ratio,
        exponent=m.exponent,
        fitted_natural_frequency_hz=fitted_fn,
        reason=_reason(law, n_imp, spc, poles, staged, hc) + lines_note + law_note,
        staged=staged,
        beyond_knee_interval=beyond,
        hunt_crossley=hc,
        penetration_over_table=_penetration_over_table(m),
        impact_onsets=onsets,
        **info,
    )


def _penetration_over_table(m: _Map) -> float | None:
    """The law's reference penetration over the table's displacement amplitude at the forcing
    frequency (:attr:`RestoringForceResult.penetration_over_table`); None without either."""
    table = float(np.hypot(*m.fit.table[0])) if m.law is not None else 0.0
    return m.law.reference_penetration / table if table > 0 else None


def _soft_reading(
    m: _Map,
    args: tuple,
    info: dict,
    classes,
    coverage: float,
    seed: int,
    rivals: list[float],
    why: str = SOFT_UNSEEN,
    chain_free: bool = False,
) -> RestoringForceResult | None:
    """Rule: beta of contacts that do not stand out of the free-flight law (or that the map
    reads below the classes, `why`), where the band is known to carry them (the caller's
    rule), by the free flight and the contact fitted jointly (:mod:`.soft_contact`); None
    where that fit describes no contacts (the refusal stands) or `f_n` was not given (the
    joint fit needs ``k``). `chain_free`: no chain is known, and the reading stands only
    where the joint law explains the record without one (:func:`~.band.chain_free_reading`)."""
    y, dtau, tau, use, period, k_given = args
    if k_given is None or m.source is None:
        return None
    # the record as recorded, its high-pass undone, and the known chain's resonance and
    # low-pass applied to the model (forward), not divided out of the record: its inverse's
    # Wiener band took the pulses' high harmonics from the record but not from the fitted
    # contact (beta 5.8 behind the rig's 284 Hz sheet read 5.11 [4.67, 5.60] through it, 5.74
    # [5.43, 6.05] as recorded)
    record = undo_highpass(y, dtau, m.corner)
    soft = fit_soft_contact(record, dtau, tau, use, period, k_given, m.fit.displacement,
                            coverage, seed, _known_response(info, dtau, record.size))  # fmt: skip
    if soft is None:
        return None
    lo, hi = soft.interval
    beta_min = _least_beta(classes)
    if chain_free and not chain_free_reading(record[use], soft.residual, period, hi, beta_min):
        return None
    if rivals:  # a known chain's other readings (its high-pass corner's ends)
        lo, hi = min(lo, *rivals), max(hi, *rivals)
    cls = str(beta_class(np.array([soft.beta]), classes)[0])
    fields = {**info, **_soft_fields(soft)}
    fields.pop("restoring_force_class", None)
    return RestoringForceResult(
        ok=True,
        beta=soft.beta,
        beta_interval=(lo, hi),
        restoring_force_class=cls,
        contact_damping_ratio=soft.contact_damping_ratio,
        exponent=1.0,
        fitted_natural_frequency_hz=None,
        reason=(
            f"{soft.n_contacts} contacts, {soft.samples_per_contact:.0f} samples each, {why}: "
            "beta from the free flight and a Kelvin-Voigt "
            f"contact fitted jointly (the contact explains {soft.share:.0%} of what the "
            "free-flight law leaves)"
        ),
        **fields,
    )


def _known_response(info: dict, dtau: float, n: int) -> np.ndarray | None:
    """A known chain's resonance and low-pass per ``rfft`` bin of the `n`-sample record
    whose high-pass is already undone, for the joint fit to pass its model through
    (forward); None without a known chain with either. The record as recorded keeps the
    mount's ring after every contact, which a contact law through no chain cannot explain
    (beta 7.6 behind a 146 Hz, zeta 0.011 mount and a 169 Hz low-pass given: no contacts
    described, refused; through the chain 7.52 [6.91, 8.18])."""
    chain = info.get("sensor")
    if chain is None or chain.source == "fitted" or not chain.has_dynamics:
        return None
    fs_hz = 2 * np.pi * info["forcing_frequency_hz"] / dtau
    return record_response(dataclasses.replace(chain, highpass_hz=0.0), fs_hz, n)


def _least_beta(classes: list[tuple[str, float, float]]) -> float:
    """The softest class's least beta (``classes``: name, low and high beta)."""
    return min(float(low) for _, low, _ in classes)


def _map_below_classes(map_beta: float | None, beta_min: float, carried: bool) -> str:
    """Rule: why the joint fit (:func:`_soft_reading`) reads in place of a map that reads its
    contacts below the classes' least beta `beta_min` (`map_beta`: its reading, or its
    refused law's), where the band is known to carry every contact (`carried`); '' elsewhere
    (the map's result stands, as it does where the joint fit describes no contacts).

    A soft contact lasts a large share of the forcing period and the free-flight law's table
    harmonics and damping absorb part of its force: the map then sees only the tips of the
    long pulses above its split and reads a law far softer than the contact (rig beta 5.8
    read 3.8, interval missing), or a misfit it refuses. The bias runs one way, down, so a
    map reading below the softest class is where the map is out of the world its intervals
    were set on; the joint fit reads the whole pulse, and a contact truly that soft reads
    the same there. Readings at or above `beta_min` are left to the map."""
    if not carried or map_beta is None or not map_beta < beta_min:
        return ""
    return (
        f"read by the force-displacement map below the softest class (beta {map_beta:.2f} < "
        f"{beta_min:g}: the map sees only the pulses' tips)"
    )


def _soft_fields(soft: SoftContactFit) -> dict[str, Any]:
    """The result's fields the joint fit of :mod:`.soft_contact` replaces."""
    return dict(
        n_impacts=soft.n_contacts,
        samples_per_contact=soft.samples_per_contact,
        contact_r2=soft.share,
        duration_ratio=soft.duration_ratio,
        free_damping_ratio=soft.free_damping_ratio,
        displacement=soft.displacement,
        velocity=soft.velocity,
        force=soft.force,
    )


def _reason(
    law: ContactLaw,
    n_imp: int,
    spc: float,
    poles: Any,
    staged: StagedLaw | None,
    hc: HuntCrossleyLaw | None = None,
) -> str:
    """The estimate's one line: impacts, samples, the law that gave beta."""
    words = f"{n_imp} impacts, {spc:.0f} samples each; contact law explains {law.r2:.0%} "
    words += "of the contact force"
    if poles is not None:
        words += (f"; beta from the contact's oscillation (< {POLE_MAX_SAMPLES} samples per "
                  f"contact; its recursion explains {poles.r2:.0%})")  # fmt: skip
    if staged is not None and staged.resolved:
        words += (f"; beta is the first-stage slope of the model's two-stage law (ratio "
                  f"{staged.ratio:.2f} held; knee at {staged.knee_fraction:.0%} of the peak "
                  f"penetration; it explains {staged.r2:.0%})")  # fmt: skip
    elif staged is not None:
        words += (f"; the map shows one slope, no knee of the model's two-stage law (ratio "
                  f"{staged.ratio:.2f}): beta is that slope, every impact read as short of the "
                  "knee (had every impact been beyond it, beta would be the slope over the "
                  "ratio)")  # fmt: skip
    if hc is not None:
        words += (f"; beta is the elastic slope at first contact of the model's Hunt-Crossley "
                  f"law (its delta*v term fitted free: {hc.dissipation_share:.0%} of the "
                  f"dissipation; it explains {hc.r2:.0%})")  # fmt: skip
    return words


def _hunt_crossley_beta(
    m: _Map, coverage: float, seed: int, interval: bool = True
) -> tuple[float, tuple[float, float], float, HuntCrossleyLaw]:
    """Rule: beta, its interval and the contact damping ratio of the law with a free
    ``delta v`` dissipation (:mod:`.hunt_crossley_law`), and that law. The interval: the
    bootstrap over impacts at the law's onset and dissipation, widened by the
    reconstruction's systematic error (:func:`widen_interval`)."""
    fit, k = m.fit, m.fit.stiffness
    law = fit_hunt_crossley_law(fit.force, fit.displacement, fit.velocity, m.labels > 0, m.law)
    beta = law.stiffness / k
    damping_ratio = float(law.damping / (2 * np.sqrt(law.stiffness)))
    if not interval:
        return beta, (np.nan, np.nan), damping_ratio, law
    g = hunt_crossley_shape(fit.displacement, fit.velocity, law.onset, law.dissipation)
    rhs = fit.force - law.damping * fit.velocity
    inside = (fit.displacement > law.onset) & (fit.force > 0)
    lo, hi = bootstrap_slope(g, rhs, inside, m.labels, m.n_impacts, beta, k, coverage,
                             np.random.default_rng(seed))  # fmt: skip
    return beta, widen_interval(beta, lo, hi, law.r2, m.spc), damping_ratio, law


def _staged_beta(
    m: _Map,
    stage_ratio: float | tuple[float, float],
    coverage: float,
    seed: int,
    interval: bool = True,
) -> tuple[float, tuple[float, float], float, StagedLaw, tuple[float, float] | None]:
    """Rule: beta, its interval and the contact damping ratio of a two-stage law with the
    model's ratio held (:mod:`.staged_law`), that law, and where its knee is not resolved
    the interval had every impact been beyond the knee.

    The interval: the bootstrap over impacts at the law's onset, knee and damping, widened
    by the reconstruction's systematic error (:func:`widen_interval`) and spanning the
    readings at the ends of the ratio's range. A map without a knee is read as impacts short
    of it (the one slope): the model's world has a knee its campaign's impacts reached
    (the discovery saw it there), and a map that shows none is either a shallow impact or a
    law without that knee (a linear rig), not evidence for impacts all beyond it. Reading
    the one slope over the ratio as a second reading of beta left 15 of 15 wrong answers of
    a two-stage model on the independent rig's linear contacts without an alarm (the
    library's reading: 1 of 15; benchmarks/bench_alarm.py, set rig_ideal).
    """
    law, fit, k = m.law, m.fit, m.fit.stiffness
    ends = np.atleast_1d(np.asarray(stage_ratio, float))
    ratio = float(np.exp(np.mean(np.log(ends))))
    near = m.labels > 0
    idx = np.arange(1, m.n_impacts + 1)
    peak = float(np.median(ndimage.maximum(fit.displacement - law.onset, m.labels, idx)))
    staged = fit_staged_law(fit.force, fit.displacement, fit.velocity, near, law, ratio, peak)
    beta = staged.stiffness / k
    damping_ratio = float(staged.damping / (2 * np.sqrt(staged.stiffness)))
    if not interval:
        return beta, (np.nan, np.nan), damping_ratio, staged, None
    g = staged_shape(fit.displacement, staged.onset, staged.knee, ratio)
    rhs = fit.force - staged.damping * fit.velocity
    inside = (fit.displacement > staged.onset) & (fit.force > 0)
    lo, hi = bootstrap_slope(g, rhs, inside, m.labels, m.n_impacts, beta, k, coverage,
                             np.random.default_rng(seed))  # fmt: skip
    lo, hi = widen_interval(beta, lo, hi, staged.r2, m.spc)
    if not staged.resolved:
        return beta, (lo, hi), damping_ratio, staged, (lo / ends.max(), hi / ends.min())
    others = [refit_at_ratio(staged, fit.force, fit.displacement, fit.velocity, near, float(r)) / k
              for r in ends if r != ratio]  # fmt: skip
    return beta, (min(lo, *others), max(hi, *others)), damping_ratio, staged, None


def _periodic_record(
    a: np.ndarray,
    fs_hz: float,
    ff: float,
    natural_frequency_hz: float | None,
    max_periods: float | None,
) -> tuple[tuple, int]:
    """The record as the map reads it: ``(y, dtau, tau, use, period, k_given)`` (polarity
    such that contact forces push ``-y`` up, cut to whole forcing periods, its ends unused:
    the wrap-around of a non-periodic record spoils the integrals there) and the polarity."""
    period = fs_hz / ff
    a = check_record(a, period, MIN_PERIODS)
    if max_periods is not None and a.size > max_periods * period:
        keep = int(max_periods * period)
        start = (a.size - keep) // 2
        a = a[start : start + keep]
    polarity = _polarity(a)
    y = a * -polarity  # contact forces push -y up
    length = periodic_length(y, period)
    y = y[:length]
    dtau = 2 * np.pi * ff / fs_hz
    tau = np.arange(length) * dtau
    use = np.ones(length, dtype=bool)
    edge = max(1, int(0.25 * period))
    use[:edge] = use[-edge:] = False
    k_given = None if natural_frequency_hz is None else (natural_frequency_hz / ff) ** 2
    return (y, dtau, tau, use, period, k_given), polarity


def _beta_of_map(
    m: _Map, use: np.ndarray, dtau: float, coverage: float, seed: int, interval: bool = True
):
    """Rule: beta, its interval, the contact damping ratio and the contact poles used (None:
    the contact law's). With few samples per contact the contact's own oscillation (its
    poles) gives beta where it fits and spans at most a half period; otherwise the contact
    law, with a bootstrap interval over impacts (``(nan, nan)`` without `interval`)."""
    law, fit, spc, k = m.law, m.fit, m.spc, m.fit.stiffness
    poles = None
    if spc < POLE_MAX_SAMPLES:
        core = _in_contact(fit, use)
        poles = fit_contact_poles(fit.force, core, dtau)
        if poles is not None:
            # contacts last at most the oscillation's half period (a damped one releases
            # earlier); longer ones, or a misfit, mean more poles than the contact's: a
            # low-pass near the contact's band in the chain
            span = spc * dtau * np.sqrt(poles.total_stiffness) / np.pi
            if poles.r2 < POLE_MIN_R2 or span > POLE_MAX_SPAN or not poles.total_stiffness > k:
                poles = None
    if poles is not None:  # few samples per contact: the contact's own oscillation
        beta = poles.total_stiffness / k - 1.0
        stiff = beta * k
        damping_ratio = float(max(2 * poles.decay - fit.damping, 0.0) / (2 * np.sqrt(stiff)))
        half = float(stats.norm.ppf(0.5 + coverage / 2)) * poles.log_se * (1 + beta) / beta
        lo, hi = widen_interval(beta, beta * np.exp(-half), beta * np.exp(half), poles.r2, spc)
        return beta, (lo, hi), damping_ratio, poles
    beta = law.stiffness / k
    damping_ratio = float(law.damping / (2 * np.sqrt(law.stiffness)))
    if not interval:
        return beta, (np.nan, np.nan), damping_ratio, None
    rng = np.random.default_rng(seed)
    lo, hi = bootstrap_beta(
        law, fit.force, fit.displacement, fit.velocity, m.labels, m.n_impacts, k, coverage, rng
    )
    lo, hi = widen_interval(beta, lo, hi, law.r2, spc)
    return beta, (lo, hi), damping_ratio, None
