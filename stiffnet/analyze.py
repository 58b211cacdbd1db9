"""Full nonlinear time-series analysis of one recording (``stiffnet analyze``).

Strings together the paper's pipeline (sections 3-5): smoothing, impact
detection, embedding delay and dimension, stationarity, determinism and the
geometric stiffness estimate, plus the restoring-force (force-state mapping)
estimate of :mod:`stiffnet.restoring_force` as a physical cross-check,
returning the curves as well as the numbers so that plots and JSON come from
one computation. numpy/scipy only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from stiffnet import nlts
from stiffnet.errors import ConfigError, SignalError, StiffnetError
from stiffnet.geometry.estimate import GeometricResult, geometric_estimate, smoothing_window
from stiffnet.nlts.stationarity import record_probes
from stiffnet.recordings.base import check_rate
from stiffnet.restoring_force import RestoringForceResult, restoring_force_estimate
from stiffnet.restoring_force.chain import sensor_from_mapping

#: Nearest-neighbour statistics (FNN, Cao, cross-prediction) use at most this many
#: samples: they converge long before, and their cost grows as N log N.
MAX_NEIGHBOUR_SAMPLES = 20_000
MAX_DIM = 8
#: Segments of the stationarity test; on a record longer than MAX_NEIGHBOUR_SAMPLES
#: they are probes spread over the whole record (nlts.stationarity.record_probes).
STATIONARITY_SEGMENTS = 8
#: Why the restoring-force estimate does not run without f_n (docs/field.md).
FN_MISSING = (
    "natural frequency unknown (give --fn HZ or a sidecar <recording>.json): the "
    "restoring-force estimate needs it, and a steady-state record does not show it"
)


@dataclass
class Analysis:
    """Numbers and curves of one analysis."""

    fs_hz: float
    n_samples: int
    ami: np.ndarray
    delay: int
    delay_rule: str
    fnn: np.ndarray
    cao_e1: np.ndarray
    cao_e2: np.ndarray
    dimension: int
    dimension_rule: str
    fnn_dimension: int | None
    cross_prediction: np.ndarray
    stationary: bool
    stationarity_spans: list[tuple[int, int]]
    determinism_factor: float
    geometric: GeometricResult
    smoothed: np.ndarray
    natural_frequency_hz: float | None = None
    restoring_force: RestoringForceResult | None = None
    restoring_force_error: str = ""

    def summary(self) -> dict[str, Any]:
        """The JSON result (keys are stable: programs read them)."""
        g = self.geometric
        off = self.cross_prediction[~np.eye(len(self.cross_prediction), dtype=bool)]
        return {
            "fs_hz": self.fs_hz,
            "n_samples": self.n_samples,
            "embedding_delay": self.delay,
            "embedding_delay_s": self.delay / self.fs_hz,
            "geometric_delay": int(g.delay),  # the attractor figure's and the inclinations' delay
            "delay_rule": self.delay_rule,
            "embedding_dimension": self.dimension,
            "dimension_rule": self.dimension_rule,
            "fnn_dimension": self.fnn_dimension,
            "stationary": self.stationary,
            "stationarity_tested": self.stationarity_tested(),
            "stationarity_segments_s": [
                [lo / self.fs_hz, hi / self.fs_hz] for lo, hi in self.stationarity_spans
            ],
            "cross_prediction_error_min": float(off.min()),
            "cross_prediction_error_max": float(off.max()),
            "determinism_factor": self.determinism_factor,
            "impacts_found": int(g.impacts.size),
            "contact_detected": bool(g.contact_detected),
            "contact_reason": g.reason,
            "inclination_before_deg": _num(g.inclination_before_deg),
            "inclination_after_deg": _num(g.inclination_after_deg),
            "inclination_method": g.method,
            "gradient_before_deg": _num(g.gradient_before_deg),
            "gradient_after_deg": _num(g.gradient_after_deg),
            "polynomial_before_deg": _num(g.polynomial_before_deg),
            "polynomial_after_deg": _num(g.polynomial_after_deg),
            "n_orbits": int(g.n_orbits),
            "geometric_beta": _num(g.geometric_beta),
            "geometric_class": g.geometric_class,
            "polarity": int(g.polarity),
            "dominant_frequency_hz": float(g.dominant_frequency_hz),
            "natural_frequency_hz": self.natural_frequency_hz,
            **self._restoring_force(),
        }

    def stationarity_tested(self) -> str:
        """Which part of the record the stationarity test read, in words."""
        spans = self.stationarity_spans
        n = len(spans)
        covered = sum(hi - lo for lo, hi in spans)
        first, last = spans[0][0] / self.fs_hz, spans[-1][1] / self.fs_hz
        if covered >= 0.99 * self.n_samples:
            return f"the whole record ({n} consecutive segments)"
        return (
            f"the whole record: {n} segments of {(spans[0][1] - spans[0][0]) / self.fs_hz:.3g} "
            f"s spread from {first:.3g} s to {last:.3g} s ({100 * covered / self.n_samples:.0f} "
            "% of the samples)"
        )

    def _restoring_force(self) -> dict[str, Any]:
        """The restoring-force estimate's fields (``restoring_force_*``) and its full summary."""
        r = self.restoring_force
        if r is None:
            d = {"ok": False, "reason": self.restoring_force_error}
            return {
                "restoring_force_beta": None,
                "restoring_force_class": None,
                "restoring_force": d,
            }
        return {
            "restoring_force_beta": _num(r.beta),
            "restoring_force_class": r.restoring_force_class,
            "restoring_force_beta_interval": list(r.beta_interval) if r.beta_interval else None,
            "restoring_force": r.to_dict(),
        }


def _num(value: float | None) -> float | None:
    """JSON has no NaN: missing numbers are null."""
    if value is None or not np.isfinite(value):
        return None
    return float(value)


#: Signals whose peak lies outside this range are rescaled before the analysis.
SAFE_PEAK = (1e-100, 1e100)


def _unit_scale(x: np.ndarray) -> np.ndarray:
    """``x`` scaled by a power of two to a peak in [0.5, 1) when its peak is extreme.

    The analysis is scale-free, and the power of two is exact; without it sums and
    variances of values near 1e307 overflow (reported as NaN the file does not have).
    """
    peak = float(np.max(np.abs(x)))
    if SAFE_PEAK[0] <= peak <= SAFE_PEAK[1]:
        return x
    return np.ldexp(x, -int(np.frexp(peak)[1]))


def analyze_signal(
    accel: np.ndarray,
    fs_hz: float,
    natural_frequency_hz: float | None = None,
    sensor: dict | None = None,
) -> Analysis:
    """Run the whole analysis on one acceleration record sampled at ``fs_hz``.

    ``natural_frequency_hz`` fixes the free-flight stiffness of the restoring-force
    estimate; without it that estimate is not run (its reason says why: never a
    silent default). ``sensor`` is the accelerometer chain's data sheet (undone as
    given; default: identified from the impacts). The stationarity test reads the whole
    record: on long records :data:`STATIONARITY_SEGMENTS` probes spread over it.
    """
    from stiffnet.inputs import natural_frequency, rate_ratio, sampling_rate

    fs_hz = check_rate(fs_hz, "analyze", SignalError)
    sampling_rate(fs_hz, "sampling rate")  # the predictor's physical ranges (1e12 Hz is not)
    fn = natural_frequency_hz
    if fn is not None:
        rate_ratio(fs_hz, natural_frequency(fn, "natural frequency"))
    if sensor is not None:  # a bad data sheet is the user's error, not a refusal
        try:
            sensor_from_mapping(sensor, fs_hz)
        except ValueError as exc:
            raise ConfigError(f"sensor: {exc}") from None
    a = np.asarray(accel)
    if a.ndim == 1 and a.size and a.dtype.kind in "fiu" and np.isfinite(a).all():
        peak = float(np.abs(a).max())
        if 0 < peak < 0.5:  # the constant check is absolute below 1: a tiny signal up first
            a = np.ldexp(a.astype(np.float64), -int(np.frexp(peak)[1]))
    x = _unit_scale(nlts.as_signal(a, 64))
    geo = geometric_estimate(x, fs_hz)
    rf, rf_error = None, FN_MISSING
    if fn is not None:
        try:
            rf = restoring_force_estimate(x, fs_hz, natural_frequency_hz=fn, sensor=sensor)
            rf_error = ""
        except StiffnetError as exc:  # the other analyses still stand
            rf_error = str(exc)
    # Analyse the smoothed signal, as the paper does before embedding (section 5.1).
    s = nlts.savgol_smooth(x, smoothing_window(geo.period_samples))
    s = (s - s.mean()) / s.std()
    part = s[:MAX_NEIGHBOUR_SAMPLES]
    max_lag = int(min(max(4 * geo.period_samples, 20), part.size // 10))
    ami = nlts.mutual_information(part, max_lag)
    delay = nlts.estimate_delay(part, max_lag=max_lag)
    tau = max(int(delay.value), 1)
    max_dim = MAX_DIM
    while max_dim > 2 and part.size < (max_dim + 2) * tau + 2 * tau + 10:
        max_dim -= 1
    e1, e2 = nlts.cao_curves(part, tau, max_dim)
    dim = nlts.cao_dimension(e1)
    fnn = nlts.false_nearest_neighbours(part, tau, max_dim)
    try:
        fnn_dim: int | None = nlts.fnn_dimension(fnn, threshold=0.05)
    except SignalError:
        fnn_dim = None  # reported as null: the fraction never fell low enough
    probes, spans = record_probes(s, STATIONARITY_SEGMENTS if s.size > part.size else 4,
                                  MAX_NEIGHBOUR_SAMPLES)  # fmt: skip
    cross = nlts.cross_prediction_errors(probes, dim, tau, n_segments=len(spans))
    _, det = nlts.kaplan_glass(part, min(dim, 4), max(tau, 2))
    return Analysis(
        fs_hz=float(fs_hz), n_samples=int(x.size), ami=ami, delay=tau,
        delay_rule=delay.rule, fnn=fnn, cao_e1=e1, cao_e2=e2, dimension=int(dim),
        dimension_rule="cao_E1_plateau", fnn_dimension=fnn_dim, cross_prediction=cross,
        stationary=bool(nlts.is_stationary(cross)), stationarity_spans=spans,
        determinism_factor=float(det), geometric=geo, smoothed=s,
        natural_frequency_hz=None if fn is None else float(fn), restoring_force=rf,
        restoring_force_error=rf_error,
    )  # fmt: skip
