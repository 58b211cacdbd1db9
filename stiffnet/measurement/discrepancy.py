"""Simulator-measurement discrepancy: normalised differences of phase-independent statistics.

For one recording, each statistic of :mod:`stiffnet.measurement.statistics`
gives a difference between simulation and measurement divided by a fixed
*tolerance* (:data:`TOLERANCES`, "a difference a person would call visible"):

======================  =================================================  =========
component               difference                                          tolerance
======================  =================================================  =========
``waveform``            RMS of (sim - meas) aligned mean waveform over the  0.15
                        RMS of the measured one (relative)
``spike_height``        ln(sim / meas) of the median spike height           0.1
``spike_width``         ln(sim / meas) of the median width at half height   0.15
``ringing``             log10 post/pre high-passed RMS, sim - meas          0.15
``harmonic_2``, ``_3``  harmonic / fundamental amplitude, sim - meas        0.03
``spectrum``            RMS over the grid of the log10 PSD difference       0.25
``impact_rate``         impacts per forcing period, sim - meas              0.1
``inclination_before``  geometric mean angle, degrees, sim - meas           3
``inclination_after``   idem after impact                                   3
======================  =================================================  =========

The **discrepancy of a recording** is the mean of the squared normalised
components it has (a component needing impacts is absent when either side
has none; then ``impact_rate`` carries the mismatch). The **discrepancy of a
campaign** is the mean over its recordings. A perfect simulator scores the
noise floor of the statistics (about 0.3-1 for the short records used here),
not zero.

Components are grouped by where they look (:data:`GROUPS`): ``contact``
(waveform, spike height and width, ringing, inclination after impact),
``free_flight`` (harmonics, inclination before impact) and ``global``
(spectrum, impact rate): the group holding most of the discrepancy says where
the model fails.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from stiffnet.measurement.statistics import SignalStatistics

TOLERANCES: dict[str, float] = {
    "waveform": 0.15,
    "spike_height": 0.1,
    "spike_width": 0.15,
    "ringing": 0.15,
    "harmonic_2": 0.03,
    "harmonic_3": 0.03,
    "spectrum": 0.25,
    "impact_rate": 0.1,
    "inclination_before": 3.0,
    "inclination_after": 3.0,
}
COMPONENTS: tuple[str, ...] = tuple(TOLERANCES)
GROUPS: dict[str, tuple[str, ...]] = {
    "contact": ("waveform", "spike_height", "spike_width", "ringing", "inclination_after"),
    "free_flight": ("harmonic_2", "harmonic_3", "inclination_before"),
    "global": ("spectrum", "impact_rate"),
}


def statistic_differences(
    measured: SignalStatistics, simulated: SignalStatistics
) -> dict[str, float]:
    """Raw (un-normalised) differences, simulation minus measurement; NaN when absent."""
    nan = float("nan")
    d = dict.fromkeys(COMPONENTS, nan)
    both = measured.has_impacts and simulated.has_impacts
    if both and measured.waveform.size and simulated.waveform.size:
        ref = float(np.sqrt(np.mean(measured.waveform**2)))
        diff = simulated.waveform - measured.waveform
        d["waveform"] = float(np.sqrt(np.mean(diff**2))) / max(ref, 1e-9)
    if both:
        for key in ("spike_height", "spike_width"):
            a, b = getattr(measured, key), getattr(simulated, key)
            if np.isfinite(a) and np.isfinite(b) and a > 0 and b > 0:
                d[key] = float(np.log(b / a))
        d["ringing"] = simulated.ringing - measured.ringing
        d["inclination_before"] = simulated.inclination_before_deg - measured.inclination_before_deg
        d["inclination_after"] = simulated.inclination_after_deg - measured.inclination_after_deg
    d["harmonic_2"] = float(simulated.harmonics[1] - measured.harmonics[1])
    d["harmonic_3"] = float(simulated.harmonics[2] - measured.harmonics[2])
    if measured.psd_f.size == simulated.psd_f.size and np.allclose(measured.psd_f, simulated.psd_f):
        d["spectrum"] = float(np.sqrt(np.mean((simulated.log_psd - measured.log_psd) ** 2)))
    d["impact_rate"] = simulated.impacts_per_period - measured.impacts_per_period
    return {k: (float(v) if np.isfinite(v) else nan) for k, v in d.items()}


def normalised_differences(
    measured: SignalStatistics, simulated: SignalStatistics
) -> dict[str, float]:
    """:func:`statistic_differences` divided by :data:`TOLERANCES` (NaN when absent)."""
    raw = statistic_differences(measured, simulated)
    return {k: v / TOLERANCES[k] for k, v in raw.items()}


def recording_discrepancy(normalised: Mapping[str, float]) -> float:
    """Mean squared normalised difference over the components present."""
    v = np.array([x for x in normalised.values() if np.isfinite(x)])
    return float(np.mean(v**2)) if v.size else float("nan")


def group_discrepancies(normalised: Mapping[str, float]) -> dict[str, float]:
    """Sum of squared normalised differences per group, over all components present.

    The groups' values add up to ``recording_discrepancy * n_present``: the
    share of each says where the disagreement is.
    """
    out = {}
    for g, keys in GROUPS.items():
        v = np.array([normalised[k] for k in keys if np.isfinite(normalised.get(k, np.nan))])
        out[g] = float(np.sum(v**2)) if v.size else 0.0
    return out


#: Where an unexplained discrepancy lives (the verdict of :mod:`stiffnet.measurement.diagnose`):
#: the spectrum is split at :data:`SENSOR_BAND_LOW` f_n into the sensor's band (with the
#: post-impact ringing) and the motion's.
WHERE: dict[str, tuple[str, ...]] = {
    "contact": ("waveform", "spike_height", "spike_width", "inclination_after", "impact_rate"),
    "free_flight": ("harmonic_2", "harmonic_3", "inclination_before"),
    "sensor_band": ("ringing", "spectrum_high"),
    "spectrum": ("spectrum_low",),
}
#: Lower edge of the sensor band, in multiples of f_n (the ringing high-pass of the statistics).
SENSOR_BAND_LOW = 10.0


def where_sums(measured: SignalStatistics, simulated: SignalStatistics) -> dict[str, float]:
    """Sum of squared normalised differences per :data:`WHERE` group (absent: 0)."""
    nd = normalised_differences(measured, simulated)
    if measured.psd_f.size == simulated.psd_f.size and np.allclose(measured.psd_f, simulated.psd_f):
        diff = simulated.log_psd - measured.log_psd
        high = measured.psd_f >= SENSOR_BAND_LOW
        for key, sel in (("spectrum_low", ~high), ("spectrum_high", high)):
            nd[key] = (
                float(np.sqrt(np.mean(diff[sel] ** 2)) / TOLERANCES["spectrum"])
                if sel.any()
                else float("nan")
            )
    return {
        g: float(sum(nd[k] ** 2 for k in keys if np.isfinite(nd.get(k, np.nan))))
        for g, keys in WHERE.items()
    }


def campaign_discrepancy(
    per_recording: Sequence[float], weights: Sequence[float] | None = None
) -> float:
    """Mean of the per-recording discrepancies (NaN recordings left out), weighted when
    ``weights`` are given (the diagnosis weighs non-repeatable recordings down)."""
    v = np.asarray(per_recording, dtype=np.float64)
    w = np.ones_like(v) if weights is None else np.asarray(weights, dtype=np.float64)
    ok = np.isfinite(v)
    return float(np.sum(w[ok] * v[ok]) / np.sum(w[ok])) if ok.any() else float("nan")


def discrepancies(
    measured: Sequence[SignalStatistics], simulated: Sequence[SignalStatistics | None]
) -> np.ndarray:
    """Per-recording discrepancies of paired statistics (a failed simulation scores NaN)."""
    out = np.full(len(measured), np.nan)
    for i, (m, s) in enumerate(zip(measured, simulated, strict=True)):
        if s is not None:
            out[i] = recording_discrepancy(normalised_differences(m, s))
    return out
