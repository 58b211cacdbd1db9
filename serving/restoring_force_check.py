"""The restoring-force cross-check of the predictor (numpy/scipy only).

One call of :func:`stiffnet.restoring_force.restoring_force_estimate` on at most
:data:`RESTORING_FORCE_PERIODS` forcing periods from the middle of the recording (the
cost stays bounded on long recordings), turned into the JSON fields of
:class:`serving.schemas.RestoringForceCheck`. A recording the method cannot read
(no contact, no forcing line, a meaningless fit) gives ``class`` null or
``no_contact`` and the reason, never an error: the cross-check must not stop a
prediction. The sensor chain (mounted resonance, anti-alias low-pass, charge
amplifier's high-pass) is identified from the recording's impacts, or taken from
the user's data sheet (``sensor``), undone before the map and reported
(``sensor``); :func:`sensor_outside_priors` says when it lies outside the sensor
chains the model was trained on, which the predictor's alarm counts.
``dissipation_gain`` / ``dissipation_share`` say whether the contact's dissipation
grows with penetration (:mod:`stiffnet.uncertainty.unseen_law`); ``law_shape`` what a
richer law than the training world's explains on held-out impacts
(:mod:`stiffnet.uncertainty.law_shape`); ``impact_peaks`` whether the force rises more than
once within an impact, a restraint that rings (:mod:`stiffnet.uncertainty.restraint_dynamics`).
A model trained with a learned two-stage law
(:func:`trained_stage_ratio`) has beta read in that law's sense, its first-stage slope
(``stage``; :mod:`stiffnet.restoring_force.staged_law`); one trained with a learned dissipation
growing with penetration (:func:`trained_penetration_dissipation`) in its elastic slope at first
contact, the ``delta v`` term fitted free (``hunt_crossley``;
:mod:`stiffnet.restoring_force.hunt_crossley_law`), and the map's own tests then judge the
law's shape from that law's onset.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from stiffnet.errors import StiffnetError
from stiffnet.restoring_force import restoring_force_estimate
from stiffnet.restoring_force.estimate import CHAIN_FIT_WHEN_NEEDED
from stiffnet.uncertainty.law_shape import law_shape_gains
from stiffnet.uncertainty.restraint_dynamics import second_peak_share
from stiffnet.uncertainty.unseen_law import (
    PENETRATION_DISSIPATION,
    chain_contact_ratio,
    trained_law_kinds,
)
from stiffnet.uncertainty.unseen_law import (
    penetration_dissipation as dissipation_gain_share,
)

#: Forcing periods the cross-check analyses (24: ~1.5 windows; bounds its cost to ~20 ms
#: without a sensor chain to fit, ~1-3 s with one).
RESTORING_FORCE_PERIODS = 24.0
#: A fitted chain's low-pass counts as unsupported where the contact law explains at most
#: this much more of the contact force through its inverse (R2): there the map as recorded
#: is read too (:func:`as_recorded_law_shape`). A Hunt-Crossley pulse is fitted as a
#: low-pass whose inverse ties (rig: 0.02-0.05 more); in-prior chains 0.01-0.03 more.
UNSUPPORTED_CHAIN_R2 = 0.05
#: A fitted stage counts as outside the training priors only beyond this factor of their
#: range (the fit's own scatter: 2-10 % in frequency on simulated chains).
PRIOR_SLACK = 1.15


def restoring_force_check(
    accel: Any,
    fs_hz: float,
    natural_frequency_hz: float,
    sensor: dict | None = None,
    stage_ratio: tuple[float, float] | None = None,
    *,
    highpass_hz: float | None = None,
    fit_chain: bool = False,
    penetration_dissipation: bool = False,
    sensor_fitted: bool = False,
) -> dict[str, Any]:
    """Restoring-force beta, class, interval and sensor chain of one recording, or the reason
    there is none. `sensor` is the data sheet's chain (then nothing is fitted); `stage_ratio`
    the model's learned two-stage law's ratio range (:func:`trained_stage_ratio`): beta is
    then that law's first-stage slope. The chain is fitted only where the record's contact
    law needs one (:data:`~stiffnet.restoring_force.estimate.CHAIN_FIT_WHEN_NEEDED`), or
    always with `fit_chain` (a campaign whose gated fits identified too few chains to pool:
    :func:`serving.campaign_chain.identify_regardless`). `highpass_hz`, without a `sensor`:
    the chain is known to have no resonance or low-pass and this high-pass corner (identified
    on another stretch of the same record), so nothing is fitted either.
    `penetration_dissipation`: the model's learned law has a Hunt-Crossley term
    (:func:`trained_penetration_dissipation`): beta is read with that term fitted free.
    `sensor_fitted`: `sensor` was fitted to recordings (a campaign's pooled chain, the chain a
    log's first check fitted), not the user's sheet: its inverse is weighted as a fitted
    chain's (:func:`~stiffnet.restoring_force.chain.inverse_noise_sigma`)."""
    try:
        r = restoring_force_estimate(
            accel,
            fs_hz,
            natural_frequency_hz=natural_frequency_hz,
            max_periods=RESTORING_FORCE_PERIODS,
            sensor=sensor,
            sensor_fitted=sensor_fitted,
            highpass_hz="auto" if highpass_hz is None else highpass_hz,
            # on a clean record the chain changes nothing, and fitting it would cost ten
            # times the rest of the prediction
            chain_fit_below_r2=_chain_fit_below_r2(highpass_hz, fit_chain),
            stage_ratio=stage_ratio,
            penetration_dissipation=penetration_dissipation,
            # the exponent read with an onset per impact, for the alarm's exponent rules
            impact_onsets=True,
        )
    except StiffnetError as exc:
        return {"class": None, "beta": None, "beta_interval": None, "reason": str(exc)}
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        # a fit that breaks numerically (non-finite Jacobian, singular system) is a
        # refusal of the cross-check, never a failure of the prediction
        reason = f"the restoring-force fit failed numerically ({type(exc).__name__})"
        return {"class": None, "beta": None, "beta_interval": None, "reason": reason}
    d = r.to_dict()
    hc = shape = peaks = None
    if r.ok and r.law is not None:  # the map's own tests for a law the training world lacks
        law = r.law
        # from the onset of the law that gave beta: the library's law, fitted to a
        # Hunt-Crossley contact, starts late, and the force before it reads as a first stage
        onset, exponent = law.onset, law.exponent
        if r.hunt_crossley is not None:
            onset, exponent = r.hunt_crossley.onset, 1.0
        peaks = second_peak_share(r.displacement, r.force, onset)
        hc = dissipation_gain_share(r.displacement, r.velocity, r.force, onset, exponent,
                                     law.reference_penetration)  # fmt: skip
        shape = law_shape_gains(r.displacement, r.velocity, r.force, onset,
                                law.reference_penetration, exponent,
                                trained_dissipation=r.hunt_crossley is not None)  # fmt: skip
        if shape is not None and r.sensor is not None:
            shape.update(as_recorded_law_shape(accel, fs_hz, natural_frequency_hz, r))
    return {
        "class": d["restoring_force_class"],
        "beta": d["beta"],
        "beta_interval": d["beta_interval"],
        # a stiffening law's own reading, before the linear springs it stands for: what the
        # model's interval is judged against (the wider one would hide a disagreement)
        "reading_interval": d["reading_interval"],
        "beta_interval_coverage": d["coverage"] if r.ok else None,
        "contact_damping_ratio": d["contact_damping_ratio"],
        "exponent": d["exponent"],
        "penetration_over_table": d["penetration_over_table"],
        "impact_onsets": d["impact_onsets"],
        "n_impacts": d["n_impacts"],
        "contact_r2": d["contact_r2"],
        "duration_ratio": d["duration_ratio"],
        "samples_per_contact": d["samples_per_contact"],
        "highpass_hz": d["highpass_hz"],
        "resonance_hz": d["resonance_hz"],
        "sensor": d["sensor"],
        "chain_contact_ratio": chain_contact_ratio(
            d["sensor"], d["beta_interval"], natural_frequency_hz
        ),
        "dissipation_gain": None if hc is None else hc[0],
        "dissipation_share": None if hc is None else hc[1],
        "law_shape": shape,
        "impact_peaks": peaks,
        "stage": d["stage"],
        "hunt_crossley": d["hunt_crossley"],
        "reason": d["reason"],
    }


def _chain_fit_below_r2(highpass_hz: float | None, fit_chain: bool) -> float:
    """Rule: the contact law's R² below which the check fits a chain: never behind a known
    chain without stages (`highpass_hz`), always on request, else where the law needs one."""
    if highpass_hz is not None:
        return -np.inf
    return np.inf if fit_chain else CHAIN_FIT_WHEN_NEEDED


def as_recorded_law_shape(
    accel: Any, fs_hz: float, natural_frequency_hz: float, r: Any
) -> dict[str, float]:
    """The within-impact ``delta v`` gain of the map as recorded, where a fitted chain with a
    low-pass was applied but is not supported (the law explains at most
    :data:`UNSUPPORTED_CHAIN_R2` more through its inverse): ``recorded_penetration_dissipation``
    and its ``_share`` (:func:`~stiffnet.uncertainty.law_shape.law_shape_gains`) and
    ``recorded_r2_loss``; empty otherwise. A dissipation growing with penetration shapes the
    pulse as a low-pass would, and its inverse then takes the term away from the map."""
    chain = r.sensor
    if chain.source != "fitted" or not chain.applied or not chain.lowpass_hz:
        return {}
    try:
        plain = restoring_force_estimate(
            accel,
            fs_hz,
            natural_frequency_hz=natural_frequency_hz,
            max_periods=RESTORING_FORCE_PERIODS,
            chain_fit_below_r2=-np.inf,
            profile_highpass_below_r2=CHAIN_FIT_WHEN_NEEDED,
        )
    except (StiffnetError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return {}
    if not plain.ok or plain.law is None:
        return {}
    loss = float(r.law.r2 - plain.law.r2)
    if loss > UNSUPPORTED_CHAIN_R2:
        return {}
    law = plain.law
    shape = law_shape_gains(plain.displacement, plain.velocity, plain.force, law.onset,
                            law.reference_penetration, law.exponent)  # fmt: skip
    if shape is None:
        return {}
    return {
        "recorded_penetration_dissipation": shape["penetration_dissipation"],
        "recorded_penetration_dissipation_share": shape["penetration_dissipation_share"],
        "recorded_r2_loss": loss,
    }


def check_sensor_sheet(sheet: Any, fs_hz: float, what: str = "sensor") -> dict[str, Any]:
    """A sensor data sheet (a mapping of :data:`SENSOR_KEYS` to numbers; ``highpass_hz`` may
    be ``"auto"``, the record's own corner) checked before any work, or a one-line
    :class:`StiffnetError` naming the bad key."""
    from stiffnet.restoring_force.chain import (
        HIGHPASS_FITTED,
        SENSOR_KEYS,
        sensor_from_mapping,
    )

    if not isinstance(sheet, dict):
        raise StiffnetError(f"{what} must be an object with keys {', '.join(SENSOR_KEYS)}")
    try:
        sensor_from_mapping(sheet, fs_hz)
    except ValueError as exc:
        raise StiffnetError(f"{what}: {exc}") from None
    # a campaign's pooled chain leaves the high-pass to each record ("auto")
    return {k: v if v == HIGHPASS_FITTED else float(v) for k, v in sheet.items()}


def sidecar_sensor(recording: Any) -> Any:
    """The ``sensor`` entry of the recording's sidecar ``<recording>.json`` (None without;
    :func:`check_sensor_sheet` judges what it holds)."""
    from stiffnet.recordings import sidecar_entry

    return sidecar_entry(recording, "sensor")


def trained_stage_ratio(priors: dict | None) -> tuple[float, float] | None:
    """The stage ratio range ``(low, high)`` of the learned two-stage law a model was trained
    with (``learned_contact`` in its card's ``data.priors``), or None.

    Only a law whose beta is its first-stage slope: a linear leading term (``exponent`` 1) on
    the mass's own penetration (no face mass). A power law's beta is its secant stiffness at
    ``d_r``, a length in the model's units that a record of unknown gain cannot place, and a
    face's law acts on a penetration the map does not see: those keep the library's reading.
    """
    params = _learned_law(priors)
    if params is not None:
        ratio = np.atleast_1d(np.asarray(params.get("knee_ratio", 1.0), dtype=float))
        if not _slope_on_own_penetration(params) or np.all(ratio == 1.0):
            return None
        if not np.all(np.isfinite(ratio)) or np.any(ratio <= 0):
            return None
        return float(ratio.min()), float(ratio.max())
    return None


def trained_penetration_dissipation(priors: dict | None) -> bool:
    """Whether a model was trained with a learned law whose dissipation grows with penetration
    (a Hunt-Crossley term of ``learned_contact`` in its card's ``data.priors``: the kind
    :data:`~stiffnet.uncertainty.unseen_law.PENETRATION_DISSIPATION` of
    :func:`~stiffnet.uncertainty.unseen_law.trained_law_kinds`) and the check can read beta
    in its sense: a linear leading term on the mass's own penetration, as for
    :func:`trained_stage_ratio` (a power law's beta is a secant at a length in the model's
    units, and a face's law acts on a penetration the map does not see)."""
    if PENETRATION_DISSIPATION not in trained_law_kinds(priors):
        return False
    params = _learned_law(priors)
    return params is not None and _slope_on_own_penetration(params)


def _learned_law(priors: dict | None) -> dict | None:
    """The parameters of the first ``learned_contact`` a model card's ``data.priors`` draws
    (probability above 0), or None."""
    for effect in (priors or {}).get("effects") or []:
        if isinstance(effect, dict) and effect.get("name") == "learned_contact":
            if effect.get("probability", 1.0) > 0:
                return effect.get("params") or {}
    return None


def _slope_on_own_penetration(params: dict) -> bool:
    """Whether a learned law's beta is a slope at first contact the map can read: a linear
    leading term (``exponent`` 1) on the mass's own penetration (no face mass)."""
    linear = np.all(np.atleast_1d(np.asarray(params.get("exponent", 1.0), float)) == 1.0)
    faces = [np.asarray(params.get(k, 0.0), float) for k in ("face_mass", "face2_mass")]
    return bool(linear and not any(np.any(f > 0) for f in faces))


def _sensor_prior(priors: dict | None) -> dict | None:
    """The ``sensor_dynamics`` entry of a model card's ``data.priors`` (None without one)."""
    for effect in (priors or {}).get("effects") or []:
        if isinstance(effect, dict) and effect.get("name") == "sensor_dynamics":
            return effect
    return None


def sensor_prior_lows(
    priors: dict | None, fs_hz: float, natural_frequency_hz: float
) -> dict[str, float]:
    """The lowest mount resonance and low-pass corner (Hz) of the model's sensor priors.

    Keys ``resonance_hz`` and ``lowpass_hz``, each present only where the card's
    ``data.priors`` ``sensor_dynamics`` entry gives it (relative to f_n or fs, or absolute).
    """
    prior = _sensor_prior(priors)
    if prior is None:
        return {}
    rel, params = prior.get("relative") or {}, prior.get("params") or {}
    lows: dict[str, float] = {}
    for key in ("resonance_hz", "lowpass_hz"):
        relative, absolute = rel.get(key), params.get(key)
        if relative:
            per = natural_frequency_hz if relative.get("per") == "natural_frequency" else fs_hz
            lows[key] = float(relative["range"][0]) * per
        elif isinstance(absolute, list | tuple):
            lows[key] = float(absolute[0])
    return lows


def sensor_outside_priors(
    sensor: dict | None, priors: dict | None, fs_hz: float, natural_frequency_hz: float
) -> tuple[float, str] | None:
    """How far (log ratio) and in words the identified chain lies outside the model's sensor
    priors (the card's ``data.priors``), or None when inside, unknown or unread.

    A resonance below the prior's lowest multiple of f_n rings in the band the model reads;
    a low-pass below its lowest fraction of fs rounds the spikes more than it ever saw; a
    high-pass above its highest corner shifts the free flight. Stages the chain lacks are
    inside (an ideal sensor is in every prior), and so is a fitted chain the map did not
    apply. A model trained without any sensor chain has every identified chain outside.
    """
    if not sensor or priors is None or sensor.get("applied") is False:
        return None  # a fitted chain the contact law rejected is no evidence of one
    prior = _sensor_prior(priors)
    fr, fl, fh = sensor.get("resonance_hz"), sensor.get("lowpass_hz"), sensor.get("highpass_hz")
    if prior is None:
        if fr or fl or (fh or 0) > 0:
            return np.inf, "a sensor chain, and the model was trained without one"
        return None
    params = prior.get("params") or {}
    lows = sensor_prior_lows(priors, fs_hz, natural_frequency_hz)
    out: list[tuple[float, str]] = []
    checks = ((fr, "resonance_hz", "mount resonance"), (fl, "lowpass_hz", "anti-alias low-pass"))
    for value, key, words in checks:
        low = lows.get(key)
        if not value or low is None:
            continue
        if value * PRIOR_SLACK < low:
            said = f"{words} at {value:.0f} Hz (the model saw {low:.0f} Hz and up)"
            out.append((float(np.log(low / value)), said))
    top = params.get("highpass_hz")
    if fh and isinstance(top, list | tuple) and fh > PRIOR_SLACK * float(top[1]):
        said = f"high-pass at {fh:.2g} Hz (the model saw up to {float(top[1]):.2g} Hz)"
        out.append((float(np.log(fh / float(top[1]))), said))
    if not out:
        return None
    return max(v for v, _ in out), "; ".join(w for _, w in out)


def with_sensor_check(
    alarm: dict[str, Any] | None, outside: tuple[float, str] | None
) -> dict[str, Any] | None:
    """The alarm with the sensor-chain check added: it fires when the identified chain lies
    outside the model's training priors (`outside`, from :func:`sensor_outside_priors`)."""
    from stiffnet.uncertainty.alarm_verdict import alarm_message

    if outside is None:
        return alarm
    if alarm is None:
        alarm = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}
    score, words = outside
    alarm = {**alarm, "scores": dict(alarm["scores"]), "thresholds": dict(alarm["thresholds"])}
    alarm["scores"]["sensor"] = float(min(score, 1e3))
    alarm["thresholds"]["sensor"] = 0.0
    alarm["fired"] = [*alarm["fired"], "sensor"]
    alarm["flag"] = True
    alarm["message"] = alarm_message(alarm["fired"]) + f" ({words})"
    return alarm
