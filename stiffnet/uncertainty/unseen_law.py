"""The alarm's unseen-contact-law check: what the restoring-force map says about the law itself.

The restoring-force estimate (:mod:`stiffnet.restoring_force`) fits a Kelvin-Voigt
power law ``F = K d_r (delta/d_r)^p + c v`` to every recording the predictor reads.
The training world's contact laws are the linear spring (paper eqs 11-12), its
Kelvin-Voigt damping and Hertz's ``p = 1.5``; these readings of the map fall outside
them on rigs whose law the training world lacks, and neither needs the model:

* **the exponent**: a well-fitted law (R2 >= :data:`EXPONENT_MIN_R2`) whose exponent
  lies in neither band the training world's laws are read in
  (:data:`TRAINING_EXPONENT_BANDS`) is a power law, or a stiffening law (a layer over
  a stiffer body, a two-stage restraint) that a power law stands in for;
* **dissipation that scales with penetration** (Hunt & Crossley, 1975,
  ``F = k delta (1 + lambda v)``): a ``delta v`` term added to the fitted law
  removes at least :data:`DISSIPATION_MIN_GAIN` of its misfit and carries most of
  the dissipation (:data:`DISSIPATION_MIN_SHARE`); a Kelvin-Voigt contact's
  dissipation is ``c v`` alone;
* **the law's shape within the impacts** (:mod:`stiffnet.uncertainty.law_shape`): a
  term the training world's laws lack (a curvature of the loading branch, a dissipation
  growing with penetration) predicts held-out impacts better than the library's law by
  at least :attr:`UnseenLawThresholds.curvature_min_gain` /
  :attr:`UnseenLawThresholds.penetration_dissipation_min_gain`; within one impact the
  penetration spans ``0 .. delta_max``, so this reads stiffening on steady records whose
  impacts all reach one depth;
* **a dissipation beyond the training world's, growing with penetration**
  (``contact_damping_ratio_max``, ``excess_damping_min_gain``): the map's Kelvin-Voigt
  damping ratio ``c_c / (2 sqrt(K))`` above the top of the ``contact_damping`` prior the
  models were trained on (0.5, ``configs/sim/default.yaml``) by more than the fit's
  scatter, *and* a within-impact ``delta v`` term of the physical sign that predicts
  held-out impacts at least a little better. A Hunt-Crossley contact, whose dissipation
  ``lambda delta v`` grows with the impact's depth, is read as a strong Kelvin-Voigt
  damper (0.56-2.0 on the independent rig); through a low-pass the ``delta v`` gain alone
  cannot tell it from a damped contact, which never needs such damping. A Kelvin-Voigt
  contact at the prior's top can read above the ceiling on a poor fit, with a ``delta v``
  gain near nil, or on a law that explains little of the force
  (``excess_damping_min_r2``).

* **a contact that lasts too long for the damping its law needs** (``long_contact_min_damping``,
  ``long_contact_min_samples``): a Kelvin-Voigt contact of damping ratio ``zeta`` lets go
  when its damper pulls harder than its spring pushes, after
  :func:`kelvin_voigt_release_ratio` of the undamped half period (0.77 at 0.5), and the
  map's ``duration_ratio`` reads that. A dissipation that vanishes at the contact's edges
  (Hunt-Crossley's ``lambda delta v`` is nil at first touch and at release) is fitted as a
  strong Kelvin-Voigt damper, yet its contacts last about the undamped half period: the
  measured duration exceeds the fitted damper's release.
* **a soft first stage** (``onset_toe_min``, ``onset_toe_min_r2``): the law, fitted with a
  free onset, starts where the stiff stage would start from zero force, and the force of a
  short soft first stage lies just outside its impacts
  (:func:`stiffnet.uncertainty.law_shape.onset_toe`): within-impact terms never see it,
  and at 1 kHz a two-stage contact of 6-7 samples leaves the hinge 2-3 of them.
* **contacts that outlast their law behind an undone chain** (``outlasting_contact_min_ratio``,
  ``outlasting_contact_min_r2``): where the sensor chain was identified and undone, a linear
  or Hertz contact lasts its fitted law's half period (shortened by its damping,
  :func:`kelvin_voigt_release_ratio`), while a soft first stage adds its own time to each
  contact that the stiff stage's law lacks. Behind a mounted accelerometer the mount's
  ringing hides the first stage's force from the stage and soft-first-stage rules, and the
  contact's duration is what remains of it (maps whose contacts last over twice the half
  period are refused by the cross-check and raise ``contact_duration``).
* **a stiffness that depends on depth** (``stage_min_gain``, ``stage_min_ratio``,
  ``stage_max_depth_spread``): a two-stage law, straight on both sides of a knee with a
  stiffness at least ``stage_min_ratio`` times higher beyond it, predicts held-out impacts
  better than any single power law (:func:`stiffnet.uncertainty.law_shape.stage_gain`), on
  impacts that reach alike depths. A two-stage
  restraint's map reads as Hertz to the power-law fit (exponent 1.3-1.6) and the model
  reads one stiffness between the stages, a class too hard; Hertz's own law and sensor
  chains bend the map smoothly, which a hinge takes only with a small stiffness ratio.
  On a map the power-law fit reads as Hertz (``power_law_stage_min_gain``) a smaller gain
  counts: there no in-world hinge of that ratio gains more than a few per cent.

None of these is read through a sensor chain the cross-check left on the map: where it saw
the mount ringing but undid no chain the check abstains (``law_through_left_mount``), and
where it undid a chain whose low-pass the record does not resolve the exponent is not read
(:func:`chain_left_on_exponent`); a chain's low-pass bends a linear law's map as a stiffening
law does.

The thresholds are read from ``configs/alarm/unseen_law.yaml``
(:func:`unseen_law_thresholds`; the defaults here where the file is missing).

Thresholds were chosen on in-distribution rigs only (``bench_robustness``'s ideal,
damped, Hertz, sensor and damped-with-sensor sets, 64-96 recordings each: at most
3 % of a set fires) and then measured on the out-of-library sets and the
independent rig (docs/crosscheck.md). numpy only: the predictor imports it.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict

from stiffnet.inputs import sensor_given
from stiffnet.uncertainty.alarm_verdict import alarm_message
from stiffnet.uncertainty.campaign_law import chain_left_on_map
from stiffnet.uncertainty.restraint_dynamics import RESTRAINT_DYNAMICS

#: Exponents the restoring-force fit reads on the training world's laws (robustness
#: sets, R2 >= 0.98): linear and Kelvin-Voigt contacts 1.00-1.16, Hertz 1.38-1.52, and
#: through a sensor chain (mount resonance, anti-alias low-pass) anything up to 1.83,
#: which is what bounds the upper band.
TRAINING_EXPONENT_BANDS = ((1.0, 1.2), (1.3, 1.85))
#: The exponent counts only from a law that explains this share of the contact force
#: (through a sensor chain the exponent of a poorer fit wanders over 1.0-3.0).
EXPONENT_MIN_R2 = 0.98
#: Where the law's own exponent does not count, the exponent read with an onset per impact
#: (``impact_onsets``, :mod:`stiffnet.restoring_force.impact_onsets`) counts from a law that
#: explains this share (the same level: an onset per impact is a nuisance of the
#: reconstruction, not a term of the law; ``inf`` leaves it out).
IMPACT_ONSET_MIN_R2 = 0.98
#: ... and from an exponent that removes at least this share of the misfit of the linear law
#: with the same onsets free (``impact_onsets.linear_r2``): a damped linear contact read
#: with an onset per impact can bend its law without the exponent explaining much (see the
#: YAML).
IMPACT_ONSET_MIN_GAIN = 0.3
#: ... and only on a contact whose fitted Kelvin-Voigt damping ratio is at most this: where
#: the damper carries most of the force at the start of each contact, an onset per impact
#: and the exponent trade off (see the YAML).
IMPACT_ONSET_MAX_DAMPING = 0.35
#: Fraction of the fitted law's misfit a ``delta v`` term must remove (in-distribution,
#: share >= 0.3: <= 0.59 on damped contacts, <= 0.16 through a sensor chain, up to 0.86
#: on a damped contact through a sensor chain, where 2 of 96 reach 0.8).
DISSIPATION_MIN_GAIN = 0.8
#: Share of the dissipation the ``delta v`` term must carry, ``h d_r / (|c| + |h d_r|)``.
DISSIPATION_MIN_SHARE = 0.3
#: Fewest in-contact samples for the ``delta v`` regression.
MIN_CONTACT_SAMPLES = 10
#: Held-out-impact gain of a stiffening curvature term (:mod:`.law_shape`) that fires
#: (in-distribution robustness sets, 24 recordings each, unalarmed: at most 0.07).
CURVATURE_MIN_GAIN = 0.15
#: Held-out-impact gain of a ``delta v`` term (:mod:`.law_shape`) that fires (a
#: Kelvin-Voigt contact through an anti-alias low-pass, whose onset jump the filter
#: smooths as Hunt-Crossley's law starts at zero, reaches 0.59; alone 0.20).
PENETRATION_DISSIPATION_MIN_GAIN = 0.65
#: Least share of the elastic force the curvature term carries (positive: stiffening; a
#: sensor chain's or a damped contact's distortion bends the law either way).
CURVATURE_MIN_SHARE = 0.1
#: Least share of the dissipation the within-impact ``delta v`` term carries (a low-pass
#: delays the force, which reads as a ``delta v`` term of the wrong sign).
PENETRATION_DISSIPATION_MIN_SHARE = 0.3
#: Fitted Kelvin-Voigt contact damping ratio above which the contact dissipates more than
#: any training contact: the prior's top, 0.5, times 1.15 (a damped contact of 0.25-0.5
#: reads up to 0.569 on 96 robustness recordings, 0.48 on 24 of the independent rig).
CONTACT_DAMPING_RATIO_MAX = 0.575
#: Within-impact ``delta v`` gain (:mod:`.law_shape`, with its physical sign) that must come
#: with a damping above :data:`CONTACT_DAMPING_RATIO_MAX` (Kelvin-Voigt contacts of zeta
#: 0.45-0.5 on the independent rig that read above it: 0.06 and 0.23 with share 0.24).
EXCESS_DAMPING_MIN_GAIN = 0.1
#: The damping counts only from a law that explains this share of the contact force (a
#: Kelvin-Voigt contact of zeta 0.49 on the independent rig read 0.79 with R2 0.53 and a
#: ``delta v`` gain of 0.33; the rig's Hunt-Crossley contacts that fire: R2 0.83-0.93).
EXCESS_DAMPING_MIN_R2 = 0.7
#: Held-out-impact gain of a two-stage law over the best single power law that fires
#: (:func:`stiffnet.uncertainty.law_shape.stage_gain`; in-distribution sets, unalarmed
#: recordings with a stage ratio of at least :data:`STAGE_MIN_RATIO`: see the YAML).
STAGE_MIN_GAIN = 0.15
#: Least stiffness ratio across the knee (a Hertz contact's hinge reads 1.5-1.7).
STAGE_MIN_RATIO = 2.0
#: The stage is judged only where the impacts reach alike depths
#: (:func:`stiffnet.uncertainty.law_shape.depth_spread` at most this; see the YAML).
STAGE_MAX_DEPTH_SPREAD = 2.0
#: Held-out-impact gain of the two-stage law that fires on a map whose counted exponent lies
#: in a training band above the linear one (read as Hertz; :func:`power_law_stage_reasons`):
#: there the in-world hinges of ratio >= :data:`STAGE_MIN_RATIO` gain at most 0.037 (see the
#: YAML), while sensor chains' maps read near-linear reach 0.13.
POWER_LAW_STAGE_MIN_GAIN = 0.075
#: Fitted Kelvin-Voigt damping ratio from which the contact's duration is judged: the law
#: then predicts a release at least 19 % before the undamped half period
#: (:func:`kelvin_voigt_release_ratio`), more than the duration's sampling error.
LONG_CONTACT_MIN_DAMPING = 0.4
#: Measured duration beyond the fitted damper's release that fires, in samples: a duration is
#: a median count of samples in contact, so one sample is its resolution (see the YAML).
LONG_CONTACT_MIN_SAMPLES = 1.25
#: Force just outside the fitted law's contact (:func:`stiffnet.uncertainty.law_shape.
#: onset_toe`), in units of the free flight's force scatter, that fires (see the YAML).
ONSET_TOE_MIN = 8.0
#: ... counted only from a law explaining this share of the contact force (a poorly fitted
#: Kelvin-Voigt contact's onset lands inside its impacts: 68-117 at R2 0.68-0.79).
ONSET_TOE_MIN_R2 = 0.95
#: ... and on neither side of the impacts a force below this (a sensor chain's ringing or
#: low-pass leaves the force after the release negative: -4 to -48 on robustness sets).
ONSET_TOE_MIN_SIDE = -1.0
#: ... and above this share of the fitted law's damped step at the onset (a Kelvin-Voigt
#: force steps to ``c v`` there, and an undone chain's band limit rings the step onto the
#: samples before it; see the YAML).
ONSET_TOE_MIN_STEP_SHARE = 0.2
#: ... unless the weaker side's force reaches this: the band limit rings the onset's step
#: onto the samples before the contact only, while a first stage pushes on both sides.
ONSET_TOE_STEP_MAX_SIDE = 1.2
#: ... or, whatever the toe, the weaker side's force at least this: both sides push (see the YAML).
ONSET_TOE_BOTH_SIDES_MIN = 2.0
#: Contact duration over the fitted Kelvin-Voigt law's release (:func:`kelvin_voigt_release_ratio`)
#: that fires, behind a sensor chain the cross-check identified and undid (see the YAML).
OUTLASTING_CONTACT_MIN_RATIO = 1.5
#: ... counted only from a law explaining this share of the contact force.
OUTLASTING_CONTACT_MIN_R2 = 0.98
#: Low end of the chain fit's contact frequency over the high end of the fitted law's (both
#: 90 % intervals, :func:`chain_contact_ratio`) that fires behind a fitted chain (see the YAML).
FAST_CHAIN_CONTACT_MIN_RATIO = 1.0
#: ... counted only from a law explaining this share of the contact force.
FAST_CHAIN_CONTACT_MIN_R2 = 0.995
#: Force on the weaker side just outside the impacts (``law_shape.toe_least_side``, in units of
#: the free flight's force scatter) at or below which a map read with no chain undone shows a
#: low-pass ringing after the release (:func:`release_ring`; see the YAML).
RELEASE_RING_MAX_SIDE = -6.0
#: An undone low-pass's corner over the chain fit's contact frequency below which the map's
#: within-impact curvature is not read as the law's (:func:`lowpass_near_contact`; see the YAML).
CURVATURE_MIN_LOWPASS_OVER_CONTACT = 1.5
#: The shipped thresholds (``configs/alarm/unseen_law.yaml``), relative to the package.
THRESHOLDS_CONFIG = "alarm/unseen_law.yaml"


class UnseenLawThresholds(BaseModel):
    """Thresholds of the ``contact_law`` check (``configs/alarm/unseen_law.yaml``)."""

    model_config = ConfigDict(extra="forbid")

    training_exponent_bands: list[tuple[float, float]] = list(TRAINING_EXPONENT_BANDS)
    exponent_min_r2: float = EXPONENT_MIN_R2
    impact_onset_min_r2: float = IMPACT_ONSET_MIN_R2
    impact_onset_min_gain: float = IMPACT_ONSET_MIN_GAIN
    impact_onset_max_damping: float = IMPACT_ONSET_MAX_DAMPING
    dissipation_min_gain: float = DISSIPATION_MIN_GAIN
    dissipation_min_share: float = DISSIPATION_MIN_SHARE
    curvature_min_gain: float = CURVATURE_MIN_GAIN
    curvature_min_share: float = CURVATURE_MIN_SHARE
    penetration_dissipation_min_gain: float = PENETRATION_DISSIPATION_MIN_GAIN
    penetration_dissipation_min_share: float = PENETRATION_DISSIPATION_MIN_SHARE
    contact_damping_ratio_max: float = CONTACT_DAMPING_RATIO_MAX
    excess_damping_min_gain: float = EXCESS_DAMPING_MIN_GAIN
    excess_damping_min_r2: float = EXCESS_DAMPING_MIN_R2
    stage_min_gain: float = STAGE_MIN_GAIN
    stage_min_ratio: float = STAGE_MIN_RATIO
    stage_max_depth_spread: float = STAGE_MAX_DEPTH_SPREAD
    power_law_stage_min_gain: float = POWER_LAW_STAGE_MIN_GAIN
    long_contact_min_damping: float = LONG_CONTACT_MIN_DAMPING
    long_contact_min_samples: float = LONG_CONTACT_MIN_SAMPLES
    onset_toe_min: float = ONSET_TOE_MIN
    onset_toe_min_r2: float = ONSET_TOE_MIN_R2
    onset_toe_min_side: float = ONSET_TOE_MIN_SIDE
    onset_toe_min_step_share: float = ONSET_TOE_MIN_STEP_SHARE
    onset_toe_step_max_side: float = ONSET_TOE_STEP_MAX_SIDE
    onset_toe_both_sides_min: float = ONSET_TOE_BOTH_SIDES_MIN
    outlasting_contact_min_ratio: float = OUTLASTING_CONTACT_MIN_RATIO
    outlasting_contact_min_r2: float = OUTLASTING_CONTACT_MIN_R2
    fast_chain_contact_min_ratio: float = FAST_CHAIN_CONTACT_MIN_RATIO
    fast_chain_contact_min_r2: float = FAST_CHAIN_CONTACT_MIN_R2
    release_ring_max_side: float = RELEASE_RING_MAX_SIDE
    curvature_min_lowpass_over_contact: float = CURVATURE_MIN_LOWPASS_OVER_CONTACT
    #: Whether the exponent counts on a map read through a sensor chain the cross-check left
    #: on it (:func:`chain_left_on_exponent`); false: it is no reading of the law.
    exponent_through_left_chain: bool = False
    #: Whether any rule judges a map read through a mount the cross-check saw ringing but
    #: did not undo (:func:`~stiffnet.uncertainty.campaign_law.chain_left_on_map`); false:
    #: the map's shape is the chain's as much as the law's, and the check abstains.
    law_through_left_mount: bool = False


@lru_cache(maxsize=1)
def unseen_law_thresholds() -> UnseenLawThresholds:
    """The shipped thresholds: ``configs/alarm/unseen_law.yaml``, else the defaults above."""
    from stiffnet.config import shipped_settings

    return shipped_settings(UnseenLawThresholds, THRESHOLDS_CONFIG)


def penetration_dissipation(
    disp: np.ndarray,
    vel: np.ndarray,
    force: np.ndarray,
    onset: float,
    exponent: float,
    reference_penetration: float,
) -> tuple[float, float] | None:
    """How much a dissipation scaling with penetration improves the fitted contact law.

    On the in-contact samples (``delta = x - onset > 0``) the law's shape is refitted
    linearly, ``F = a (delta/d_r)^p + b + c v``, then with ``h (delta/d_r) v`` added
    (Hunt-Crossley's term). Returns ``(gain, share)``: the fraction of the first
    fit's residual sum of squares the term removes, and its share of the
    dissipation at the reference penetration, ``h / (|c| + |h|)`` (positive when
    the dissipation grows with penetration). None with too few contact samples.
    """
    d = np.asarray(disp, float) - onset
    on = d > 0
    if int(on.sum()) < MIN_CONTACT_SAMPLES or not reference_penetration > 0:
        return None
    dn = d[on] / reference_penetration
    f, v = np.asarray(force, float)[on], np.asarray(vel, float)[on]
    base = np.column_stack([dn**exponent, np.ones_like(dn), v])
    full = np.column_stack([base, dn * v])
    sse = []
    for a in (base, full):
        coef = np.linalg.lstsq(a, f, rcond=None)[0]
        sse.append(float(np.sum((f - a @ coef) ** 2)))
    if not sse[0] > 0:
        return None
    c, h = float(coef[2]), float(coef[3])
    return 1.0 - sse[1] / sse[0], h / (abs(c) + abs(h) + 1e-300)


#: The kinds of law the ``contact_law`` check tells from the library's: a law stiffer the
#: deeper it is pressed (an exponent, a curvature, stages, a soft first stage) and a
#: dissipation growing with penetration (Hunt-Crossley's).
STIFFENING = "stiffening"
PENETRATION_DISSIPATION = "penetration_dissipation"


def trained_law_kinds(priors: dict[str, Any] | None) -> frozenset[str]:
    """The kinds of law beyond the library's that a model's training world had.

    A model the loop retrained with a learned law (``learned_contact`` in its card's
    ``data.priors["effects"]``) saw it: a knee with a stiffness ratio other than 1 or an
    exponent other than 1 is :data:`STIFFENING`, a Hunt-Crossley term
    :data:`PENETRATION_DISSIPATION`, a face with a mass of its own
    :data:`~stiffnet.uncertainty.restraint_dynamics.RESTRAINT_DYNAMICS` (the
    ``restraint_dynamics`` check then does not judge). The ``contact_law`` check then does
    not call those kinds unseen (:func:`unseen_law_reasons`' ``seen``). The shipped models'
    worlds have none: an empty set.
    """
    kinds: set[str] = set()
    for effect in (priors or {}).get("effects") or []:
        if effect.get("name") != "learned_contact" or not effect.get("probability", 1.0) > 0:
            continue
        params = effect.get("params") or {}
        if _departs(params.get("knee_ratio"), 1.0) or _departs(params.get("exponent"), 1.0):
            kinds.add(STIFFENING)
        if _departs(params.get("hunt_crossley"), 0.0):
            kinds.add(PENETRATION_DISSIPATION)
        if any(_departs(params.get(k), 0.0) for k in ("face_mass", "face2_mass")):
            kinds.add(RESTRAINT_DYNAMICS)
    return frozenset(kinds)


def _departs(value: Any, neutral: float) -> bool:
    """A prior's value (a number or a ``[low, high]`` range) reaches beyond ``neutral``."""
    if value is None:
        return False
    values = np.atleast_1d(np.asarray(value, dtype=float))
    return bool(np.any(values != neutral))


def unseen_law_reasons(
    restoring_force: dict[str, Any],
    thresholds: UnseenLawThresholds | None = None,
    seen: frozenset[str] = frozenset(),
) -> list[str]:
    """Why the restoring-force map reads a contact law the training world lacks (empty: none).

    ``restoring_force`` holds the cross-check's fields
    (:func:`serving.restoring_force_check.restoring_force_check`):
    ``exponent``, ``contact_r2``, ``dissipation_gain`` / ``dissipation_share``,
    ``contact_damping_ratio`` and ``law_shape``
    (:func:`stiffnet.uncertainty.law_shape.law_shape_gains`).
    `thresholds` default to :func:`unseen_law_thresholds`. `seen`: the kinds of law the
    model was trained on (:func:`trained_law_kinds`), whose reasons are left out. None on a
    map read through a mount the cross-check saw ringing but did not undo
    (:func:`~stiffnet.uncertainty.campaign_law.chain_left_on_map`, unless
    ``law_through_left_mount``): the chain's low-pass and what the division of the ringing
    missed shape that map as much as the law does (the training world's sensor sets: exponents
    1.23-2.01, curvature gains 0.17-0.49, a within-impact ``delta v`` of 0.66 on right
    answers), and no unseen-law set's firing map is such a map.
    """
    t = thresholds or unseen_law_thresholds()
    if not t.law_through_left_mount and chain_left_on_map(restoring_force):
        return []
    reasons = []
    if STIFFENING not in seen:
        reasons += stiffening_reasons(restoring_force, t)
    if PENETRATION_DISSIPATION not in seen:
        reasons += dissipation_reasons(restoring_force, t)
    return reasons


def exponent_reading(
    restoring_force: dict[str, Any], t: UnseenLawThresholds
) -> tuple[float, float, str] | None:
    """Rule: the contact exponent that counts, as ``(p, R2, how it was read)``: the law's own
    where it explains ``exponent_min_r2`` of the contact force, else the law refitted with an
    onset per impact (``impact_onsets``) where that explains ``impact_onset_min_r2`` and its
    exponent removes ``impact_onset_min_gain`` of the misfit of the linear law with the same
    onsets (:func:`impact_onset_gain`), on a contact damped at most
    ``impact_onset_max_damping``; None where neither counts, or where the map was read
    through a sensor chain the cross-check left on it (:func:`chain_left_on_exponent`,
    unless ``exponent_through_left_chain``). A map whose level wanders between impacts
    smears a power law into a line at one onset (:mod:`stiffnet.restoring_force.impact_onsets`)."""
    if not t.exponent_through_left_chain and chain_left_on_exponent(restoring_force, t):
        return None
    p, r2 = restoring_force.get("exponent"), restoring_force.get("contact_r2")
    if p is not None and r2 is not None and r2 >= t.exponent_min_r2:
        return float(p), float(r2), "the law"
    onsets = restoring_force.get("impact_onsets") or {}
    p, r2, linear = onsets.get("exponent"), onsets.get("r2"), onsets.get("linear_r2")
    if p is None or r2 is None or linear is None or r2 < t.impact_onset_min_r2:
        return None
    if impact_onset_gain(r2, linear) < t.impact_onset_min_gain:
        return None
    zeta = restoring_force.get("contact_damping_ratio")
    if zeta is None or zeta > t.impact_onset_max_damping:
        return None
    return float(p), float(r2), "an onset per impact"


def chain_left_on_exponent(
    restoring_force: dict[str, Any] | None, thresholds: UnseenLawThresholds | None = None
) -> str | None:
    """Rule: why the map's exponent is partly a sensor chain's (None: read it as the law's).

    A low-pass in the chain delays and rounds each contact pulse, which bends a linear law's
    force-penetration map as a stiffening exponent does (the training world's sensor sets
    read linear contacts at 1.2-2.1 through such chains). The exponent is partly the chain's
    where the record shows a chain the cross-check did not resolve:

    * the mount's ringing was divided out (``resonance_hz``) but no chain was undone
      (``sensor`` absent or not ``applied``): whatever low-pass the chain has is still on
      the map (the campaign rule's :func:`~stiffnet.uncertainty.campaign_law.chain_left_on_map`);
    * a chain with a resonance or a high-pass was undone, but the record does not exclude
      low-passes of the priors other than the one fitted (``sensor.lowpass_not_excluded``):
      the map, and its exponent, depend on which of them the chain has;
    * no chain was undone and the map's force pulls after the release
      (:func:`release_ring`): a low-pass the cross-check did not identify rings there.

    A high-pass corner read alone, or an undone "chain" of nothing but unexcluded low-passes,
    is no evidence of a chain: records without any read corners of 0.1-1.5 Hz (damped
    contacts, drifts) and have a damped contact fitted as a low-pass, the unseen laws among
    them (bench_alarm's two-stage rig at seed offset 1000: a wrong answer whose only alarm
    was the exponent went silent when those counted).

    The curvature, stage and soft-first-stage rules keep judging such a map (a two-stage
    law's hinge is no low-pass's bend), the curvature except behind a ringing release;
    the exponent rule, the stage rule's Hertz-read variant and the ``reference_penetration``
    check, which read the exponent, do not. `thresholds` default to
    :func:`unseen_law_thresholds`.
    """
    rf = restoring_force or {}
    sensor = rf.get("sensor") or {}
    if sensor.get("applied"):
        seen = sensor.get("resonance_hz") is not None or (sensor.get("highpass_hz") or 0.0) > 0
        left = [
            f"{float(lp['hz']):.0f} Hz order {int(lp['order'])}"
            for lp in sensor.get("lowpass_not_excluded") or []
            if lp.get("hz") is not None and lp.get("order") is not None
        ]
        if not (seen and left):
            return None
        return (
            f"the sensor chain was undone, but the record does not exclude the priors' "
            f"low-pass{'es' * (len(left) > 1)} {', '.join(left)}, and the map's exponent "
            "depends on which low-pass the chain has"
        )
    if not chain_left_on_map(rf):
        return release_ring(rf, thresholds or unseen_law_thresholds())
    return (
        f"the record shows a mount ringing at {float(rf['resonance_hz']):.0f} Hz, a sensor "
        "chain the cross-check did not undo: its low-pass is still on the map and bends a "
        "linear law's map as a stiffening exponent does"
    )


def release_ring(restoring_force: dict[str, Any] | None, t: UnseenLawThresholds) -> str | None:
    """Rule: a map read with no chain undone whose force pulls after the release, the ringing
    of a sensor low-pass the cross-check did not identify (None: no such ring).

    A low-pass delays and rounds each contact pulse and rings below zero after it: on the map
    the force on the samples just outside the impacts is negative on one side
    (:func:`stiffnet.uncertainty.law_shape.onset_toe`'s ``toe_least_side``), while a contact
    law pushes or is at rest there. The same delay bends a linear law's loading branch as a
    stiffening exponent or a within-impact curvature does, so neither is the law's. Where the
    cross-check identified and undid a chain (``sensor.applied``) the other rules of
    :func:`chain_left_on_exponent` judge what is left of it. Fires at or below
    ``release_ring_max_side`` (see the YAML for the readings behind it).
    """
    rf = restoring_force or {}
    if (rf.get("sensor") or {}).get("applied"):
        return None
    least = (rf.get("law_shape") or {}).get("toe_least_side")
    if least is None or not least <= t.release_ring_max_side:
        return None
    return (
        f"the cross-check undid no sensor chain, yet the map's force pulls after the release "
        f"({float(least):.1f} times the free flight's scatter): a low-pass rings there, and "
        "its delay bends a linear law's map as a stiffening exponent or curvature does"
    )


def lowpass_near_contact(
    restoring_force: dict[str, Any] | None, t: UnseenLawThresholds
) -> str | None:
    """Rule: a map read through an undone low-pass whose corner lies within
    ``curvature_min_lowpass_over_contact`` times the contact pulse's frequency (the chain
    fit's ``sensor.contact_hz``), where the within-impact curvature is the inverse's, not the
    law's (None: read it).

    Undoing a low-pass near the contact's band amplifies what the fitted corner, the
    sampling and the noise leave of the pulse's top, and that bends a linear law's loading
    branch as stiffening does: a linear contact behind a 90 Hz 2nd-order low-pass at 1 kHz
    reads curvature gains of 0.28-0.37 through the chain pooled over the campaign and through
    its true corner alike, on contacts at 0.67-1.03 times the corner (see the YAML).
    """
    sensor = (restoring_force or {}).get("sensor") or {}
    corner, contact = sensor.get("lowpass_hz"), sensor.get("contact_hz")
    if not sensor.get("applied") or not corner or not contact:
        return None
    if not float(corner) < t.curvature_min_lowpass_over_contact * float(contact):
        return None
    return (
        f"the sensor chain's {float(corner):.0f} Hz low-pass was undone within "
        f"{t.curvature_min_lowpass_over_contact:g} times the contact's {float(contact):.0f} Hz: "
        "its inverse bends the map within each impact as a stiffening law does"
    )


def impact_onset_gain(r2: float, linear_r2: float) -> float:
    """Share of the linear law's misfit (the same onsets free) the exponent removes."""
    return 1.0 - (1.0 - r2) / max(1.0 - linear_r2, 1e-12)


def stiffening_reasons(restoring_force: dict[str, Any], t: UnseenLawThresholds) -> list[str]:
    """The :data:`STIFFENING` rules: the exponent (:func:`exponent_reading`), a curvature
    within the impacts, stages and a soft first stage (its force outside the law's
    contacts, or its time: :func:`outlasting_contact_reasons`; or a pulse faster than its
    law behind a fitted chain: :func:`fast_chain_contact_reasons`)."""
    reasons = []
    reading = exponent_reading(restoring_force, t)
    if reading is not None:
        p, r2, how = reading
        if not any(lo <= p <= hi for lo, hi in t.training_exponent_bands):
            reasons.append(
                f"contact exponent {p:.2f} (R2 {r2:.3f}, {how}) is outside what linear and "
                "Hertz contacts read"
            )
    shape = restoring_force.get("law_shape")
    r2 = restoring_force.get("contact_r2")
    stages = stage_reasons(shape, t) or power_law_stage_reasons(shape, reading, t)
    if t.exponent_through_left_chain or not (
        release_ring(restoring_force, t) or lowpass_near_contact(restoring_force, t)
    ):
        reasons += curvature_reasons(shape, t)  # a ringing low-pass bends it as it does p
    reasons += stages
    return (
        reasons
        + onset_toe_reasons(shape, r2, t)
        + outlasting_contact_reasons(restoring_force, t)
        + fast_chain_contact_reasons(restoring_force, t)
    )


def chain_contact_ratio(
    sensor: dict[str, Any] | None,
    beta_interval: list[float] | None,
    natural_frequency_hz: float,
) -> list[float] | None:
    """The contact frequency the chain fit read over the one the fitted law implies.

    A fitted chain (:func:`stiffnet.restoring_force.chain.identify_sensor_chain`) is fitted
    jointly with a linear contact pulse of frequency ``contact_hz``; the law the map then
    fits (through the chain where it was undone) implies ``f_n sqrt(1 + beta)``. On a linear
    contact the two agree (the independent rig behind its lab mount: 0.98-1.06).

    Parameters
    ----------
    sensor : dict or None
        The restoring-force check's ``sensor`` (``source``, ``resonance_hz``,
        ``lowpass_hz``, ``contact_hz``, ``intervals``).
    beta_interval : list of float or None
        The restoring-force beta interval.
    natural_frequency_hz : float

    Returns
    -------
    list of float or None
        ``[low, high]``: the ratio's range over both 90 % intervals (the chain's low end over
        the law's high end, and the reverse). None where no chain with a resonance or
        low-pass was fitted, or either interval is missing or not finite.
    """
    if not sensor or sensor.get("source") != "fitted" or not beta_interval:
        return None
    if not (sensor.get("resonance_hz") or sensor.get("lowpass_hz")):
        return None  # a high-pass alone: the pulse is the law's, no joint fit to compare
    contact = (sensor.get("intervals") or {}).get("contact_hz")
    if not contact or not natural_frequency_hz > 0:
        return None
    lo_beta, hi_beta = beta_interval
    values = (contact[0], contact[1], lo_beta, hi_beta)
    if not all(v is not None and np.isfinite(v) and v > -1.0 for v in values):
        return None
    law_lo = natural_frequency_hz * np.sqrt(1.0 + lo_beta)
    law_hi = natural_frequency_hz * np.sqrt(1.0 + hi_beta)
    if not (law_lo > 0 and contact[0] > 0):
        return None
    return [float(contact[0] / law_hi), float(contact[1] / law_lo)]


def fast_chain_contact_reasons(
    restoring_force: dict[str, Any], t: UnseenLawThresholds
) -> list[str]:
    """Rule: where the cross-check fitted a chain, on a law explaining at least
    :attr:`UnseenLawThresholds.fast_chain_contact_min_r2` of the contact force, the chain
    fit's linear contact pulse is faster than the law the map fits: the low end of
    their ratio (``chain_contact_ratio``, :func:`chain_contact_ratio`) reaches
    :attr:`UnseenLawThresholds.fast_chain_contact_min_ratio`. A two-stage restraint behind a
    mount reads as a plausible linear law of the stiff stage, which the model reads too; the
    pulse the joint fit reads agrees with no one linear law. Only the faster side counts:
    the slower one occurs on a linear contact (see the YAML)."""
    ratio, r2 = restoring_force.get("chain_contact_ratio"), restoring_force.get("contact_r2")
    if not ratio or r2 is None or not r2 >= t.fast_chain_contact_min_r2:
        return []
    if not ratio[0] >= t.fast_chain_contact_min_ratio:
        return []
    return [
        f"the chain fit's contact pulse is {ratio[0]:.2f}-{ratio[1]:.2f} times as fast as the "
        f"fitted law (R2 {r2:.3f}) through the fitted sensor chain: no one linear contact gives "
        "both, as a soft first stage before a stiff one does, and the model reads the stiff stage"
    ]


def outlasting_contact_reasons(
    restoring_force: dict[str, Any], t: UnseenLawThresholds
) -> list[str]:
    """Rule: behind a sensor chain the cross-check identified and undid (``sensor.applied``),
    on a law explaining at least :attr:`UnseenLawThresholds.outlasting_contact_min_r2` of the
    contact force, the contacts last at least
    :attr:`UnseenLawThresholds.outlasting_contact_min_ratio` times the fitted law's release
    (the undamped half period shortened by its damping, :func:`kelvin_voigt_release_ratio`):
    a soft first stage adds its time to each contact, which the stiff stage's law, the one the
    map and the model read, lacks. A chain that was not undone stretches the contacts itself
    and is not judged; from a damping of
    :attr:`UnseenLawThresholds.long_contact_min_damping` long contacts are
    :func:`long_contact_reasons`' (a dissipation that vanishes at the contact's edges)."""
    if not (restoring_force.get("sensor") or {}).get("applied"):
        return []
    r2, duration = restoring_force.get("contact_r2"), restoring_force.get("duration_ratio")
    zeta = restoring_force.get("contact_damping_ratio")
    values = (r2, duration, zeta)
    if any(v is None or not np.isfinite(v) for v in values) or r2 < t.outlasting_contact_min_r2:
        return []
    if zeta >= t.long_contact_min_damping:
        return []  # a strongly damped contact's long contacts read as Hunt-Crossley's
    release = kelvin_voigt_release_ratio(zeta)
    if not duration >= t.outlasting_contact_min_ratio * release:
        return []
    return [
        f"the contacts last {duration:.2f} of the fitted law's half period (its damping, "
        f"{zeta:.2f}, lets them last {release:.2f}) with the sensor chain undone: a soft first "
        "stage adds its time to each contact, and the model reads the stiff stage"
    ]


def dissipation_reasons(restoring_force: dict[str, Any], t: UnseenLawThresholds) -> list[str]:
    """The :data:`PENETRATION_DISSIPATION` rules: a ``delta v`` term, a damping beyond the
    prior's, contacts outlasting their damper, the within-impact ``delta v`` gain."""
    reasons = []
    gain, share = restoring_force.get("dissipation_gain"), restoring_force.get("dissipation_share")
    if gain is not None and share is not None:
        if gain >= t.dissipation_min_gain and share >= t.dissipation_min_share:
            reasons.append(
                f"the contact's dissipation grows with penetration (a delta*v term removes "
                f"{gain:.0%} of the Kelvin-Voigt law's misfit)"
            )
    r2 = restoring_force.get("contact_r2")
    if r2 is not None and r2 >= t.excess_damping_min_r2:
        zeta = restoring_force.get("contact_damping_ratio")
        reasons += excess_damping_reasons(zeta, restoring_force.get("law_shape"), t)
        reasons += long_contact_reasons(
            zeta,
            restoring_force.get("duration_ratio"),
            restoring_force.get("samples_per_contact"),
            t,
        )
    return reasons + penetration_dissipation_reasons(restoring_force.get("law_shape"), t)


def kelvin_voigt_release_ratio(zeta: float) -> float:
    """Duration of a Kelvin-Voigt contact over the undamped half period ``pi / omega``.

    In contact, ``delta'' + 2 zeta omega delta' + omega^2 delta = 0`` from first touch
    (``delta = 0``, ``delta' > 0``); the restraint lets go where its force
    ``omega^2 delta + 2 zeta omega delta'`` falls to zero, before ``delta`` does. That is at
    ``omega_d t = pi - 2 arcsin(zeta)``, so the ratio is ``2 arccos(zeta) / (pi sqrt(1 -
    zeta^2))`` (1 undamped, 0.77 at 0.5, 2/pi at critical damping; its ``arccosh`` form
    beyond). The outer spring, small against the contact's, is left out.

    Examples
    --------
    >>> round(kelvin_voigt_release_ratio(0.5), 3)
    0.77
    """
    z = max(float(zeta), 0.0)
    if abs(z - 1.0) < 1e-9:
        return 2.0 / np.pi
    if z < 1.0:
        return 2.0 * float(np.arccos(z)) / (np.pi * np.sqrt(1.0 - z * z))
    return 2.0 * float(np.arccosh(z)) / (np.pi * np.sqrt(z * z - 1.0))


def long_contact_reasons(
    zeta: float | None,
    duration_ratio: float | None,
    samples_per_contact: float | None,
    t: UnseenLawThresholds,
) -> list[str]:
    """Rule: a fitted Kelvin-Voigt damping ratio `zeta` of at least
    :attr:`UnseenLawThresholds.long_contact_min_damping`, whose contact should let go early
    (:func:`kelvin_voigt_release_ratio`), while the measured contacts (`duration_ratio` of the
    undamped half period, `samples_per_contact` samples) outlast that release by at least
    :attr:`UnseenLawThresholds.long_contact_min_samples` samples: a dissipation that vanishes
    at the contact's edges (Hunt-Crossley's grows with penetration), which the model never
    saw. The caller requires a law explaining at least
    :attr:`UnseenLawThresholds.excess_damping_min_r2` of the contact force."""
    values = (zeta, duration_ratio, samples_per_contact)
    if any(v is None or not np.isfinite(v) for v in values) or not duration_ratio > 0:
        return []
    if not zeta >= t.long_contact_min_damping:
        return []
    release = kelvin_voigt_release_ratio(zeta)
    # the half period in samples is samples_per_contact / duration_ratio
    excess = (duration_ratio - release) * samples_per_contact / duration_ratio
    if excess < t.long_contact_min_samples:
        return []
    return [
        f"the contacts last {duration_ratio:.2f} of an undamped half period ({excess:.1f} "
        f"samples longer than the Kelvin-Voigt damping the law needs, {zeta:.2f}, would let "
        f"them, releasing at {release:.2f}): a dissipation that vanishes at the contact's "
        "edges, growing with penetration like Hunt-Crossley's"
    ]


def onset_toe_reasons(
    shape: dict[str, float] | None, r2: float | None, t: UnseenLawThresholds
) -> list[str]:
    """Rule: the contact force just outside the fitted law's contact
    (:func:`stiffnet.uncertainty.law_shape.onset_toe`) reaches
    :attr:`UnseenLawThresholds.onset_toe_min` times the free flight's scatter, on a law
    explaining at least :attr:`UnseenLawThresholds.onset_toe_min_r2` of the contact force,
    with neither side of the impacts below :attr:`UnseenLawThresholds.onset_toe_min_side`
    (a sensor chain's ringing pulls after the release) and the toe above
    :attr:`UnseenLawThresholds.onset_toe_min_step_share` of the fitted law's damped step at
    the onset (``toe_damped_step``: a Kelvin-Voigt force steps to ``c v`` there, and an
    undone chain's band limit rings part of the step onto the samples before the contact;
    judged so only where the weaker side stays below
    :attr:`UnseenLawThresholds.onset_toe_step_max_side`, as that ringing leaves the samples
    after the release alone): the restraint pushes before the law starts, a soft first
    stage the law cuts off. Where both sides push by at least
    :attr:`UnseenLawThresholds.onset_toe_both_sides_min` the toe need not reach
    ``onset_toe_min``: a chain's ring or step lies on one side only, a first stage's force on
    both as the sampling phase falls."""
    if not shape or shape.get("toe") is None or r2 is None or r2 < t.onset_toe_min_r2:
        return []
    toe, least = shape["toe"], shape.get("toe_least_side", 0.0)
    both_sides = [
        f"the contact pushes before the fitted law's onset and after its release (the force "
        f"just outside each impact, on the weaker side, is {least:.1f} times the free flight's "
        "scatter): a soft first stage that the law cuts off, as a two-stage restraint has, and "
        "the model reads the stiff stage"
    ]
    if toe < t.onset_toe_min or least < t.onset_toe_min_side:
        return both_sides if least >= t.onset_toe_both_sides_min else []
    one_sided = least < t.onset_toe_step_max_side
    if one_sided and toe < t.onset_toe_min_step_share * shape.get("toe_damped_step", 0.0):
        return []
    return [
        f"the contact pushes before the fitted law's onset (the force just outside each "
        f"impact is {toe:.0f} times the free flight's scatter): a soft first stage that the "
        "law cuts off, as a two-stage restraint has, and the model reads the stiff stage"
    ]


def stage_reasons(
    shape: dict[str, float] | None, t: UnseenLawThresholds, min_gain: float | None = None
) -> list[str]:
    """Rule: a two-stage law (:func:`stiffnet.uncertainty.law_shape.stage_gain`) predicts
    held-out impacts at least :attr:`UnseenLawThresholds.stage_min_gain` (or `min_gain`)
    better than any single power law, with a stiffness ratio across its knee of at least
    :attr:`UnseenLawThresholds.stage_min_ratio`: the stiffness depends on the depth. Judged
    only on impacts of alike depths (``depth_spread`` at most
    :attr:`UnseenLawThresholds.stage_max_depth_spread`): across grazes and deep impacts the
    reconstruction's level wander reads as a stiffness rising with depth."""
    if not shape or shape.get("stage") is None:
        return []
    gain, ratio = shape["stage"], shape.get("stage_ratio", 1.0)
    least = t.stage_min_gain if min_gain is None else min_gain
    if gain < least or ratio < t.stage_min_ratio:
        return []
    if shape.get("depth_spread", 1.0) > t.stage_max_depth_spread:
        return []
    return [
        f"the contact's stiffness depends on the depth: it rises {ratio:.1f}-fold beyond "
        f"{shape.get('stage_knee', 0.0):.0%} of the reference penetration (a two-stage law "
        f"predicts held-out impacts {gain:.0%} better than any single power law), and the "
        "model reads one stiffness between the stages"
    ]


def power_law_stage_reasons(
    shape: dict[str, float] | None,
    reading: tuple[float, float, str] | None,
    t: UnseenLawThresholds,
) -> list[str]:
    """Rule: on a map whose counted exponent (`reading`, :func:`exponent_reading`) lies in a
    training band above the linear one (read as Hertz, the best single power law), the stage
    rule (:func:`stage_reasons`) with a gain of
    :attr:`UnseenLawThresholds.power_law_stage_min_gain`. A Hertz contact's own hinge reads a
    ratio under 2; a stage at least that steep over a Hertz-read map is a stiffness that
    changes at a depth, which the power law only stands in for. Maps read near-linear keep
    :attr:`UnseenLawThresholds.stage_min_gain`: a sensor chain bends those with hinges of
    ratio over 2 that gain more."""
    if reading is None:
        return []
    bands = sorted(t.training_exponent_bands)
    if not any(lo <= reading[0] <= hi for lo, hi in bands[1:]):
        return []
    return stage_reasons(shape, t, min_gain=t.power_law_stage_min_gain)


def excess_damping_reasons(
    zeta: float | None, shape: dict[str, float] | None, t: UnseenLawThresholds
) -> list[str]:
    """Rule: a Kelvin-Voigt damping ratio `zeta` above the training prior's ceiling, with a
    within-impact ``delta v`` term (:mod:`.law_shape`) of the physical sign (its share at
    least :attr:`UnseenLawThresholds.penetration_dissipation_min_share`) and gain at least
    :attr:`UnseenLawThresholds.excess_damping_min_gain`: a dissipation growing with
    penetration that the model never saw (Hunt-Crossley)."""
    if zeta is None or not zeta > t.contact_damping_ratio_max or not shape:
        return []
    gain = shape.get("penetration_dissipation")
    share = shape.get("penetration_dissipation_share", 0.0)
    if gain is None or gain < t.excess_damping_min_gain:
        return []
    if share < t.penetration_dissipation_min_share:
        return []
    return [
        f"the contact dissipates more than any the model was trained on (Kelvin-Voigt "
        f"damping ratio {zeta:.2f} fitted, above {t.contact_damping_ratio_max:.2f}), and "
        f"more the deeper it is pressed (a delta*v term predicts held-out impacts "
        f"{gain:.0%} better): a dissipation law like Hunt-Crossley's"
    ]


def law_shape_reasons(shape: dict[str, float] | None, t: UnseenLawThresholds) -> list[str]:
    """Rule: a richer term (:mod:`.law_shape`) predicts held-out impacts better by at least
    its gain threshold, with the sign of the physics it stands for (its share at least the
    share threshold: a stiffening law, a dissipation growing with penetration)."""
    return curvature_reasons(shape, t) + penetration_dissipation_reasons(shape, t)


def curvature_reasons(shape: dict[str, float] | None, t: UnseenLawThresholds) -> list[str]:
    """:func:`law_shape_reasons`' stiffening term: a curvature of the loading branch."""
    if not shape:
        return []
    curvature, share = shape.get("curvature"), shape.get("curvature_share", 1.0)
    if curvature is None or curvature < t.curvature_min_gain or share < t.curvature_min_share:
        return []
    return [
        f"the contact stiffens within each impact (a curvature term predicts held-out "
        f"impacts {curvature:.0%} better than the linear or Hertz law)"
    ]


def penetration_dissipation_reasons(
    shape: dict[str, float] | None, t: UnseenLawThresholds
) -> list[str]:
    """:func:`law_shape_reasons`' dissipation term: a ``delta v`` term within the impacts, on
    the record as read or as recorded."""
    if not shape:
        return []
    for key, where in (("", ""), ("recorded_", " of the record as recorded")):
        hc = shape.get(key + "penetration_dissipation")
        share = shape.get(key + "penetration_dissipation_share", 1.0)
        if hc is not None and hc >= t.penetration_dissipation_min_gain:
            if share >= t.penetration_dissipation_min_share:
                return [
                    f"the contact's dissipation grows with penetration within each impact{where} "
                    f"(a delta*v term predicts held-out impacts {hc:.0%} better than "
                    "Kelvin-Voigt)"
                    + (
                        ", which a fitted low-pass the law barely needs had taken away"
                        if key
                        else ""
                    )  # fmt: skip
                ]
    return []


def with_unseen_law_check(
    alarm: dict[str, Any] | None,
    restoring_force: dict[str, Any],
    seen: frozenset[str] = frozenset(),
) -> dict[str, Any] | None:
    """The alarm with the ``contact_law`` check added (fires on any :func:`unseen_law_reasons`).

    Its score is the number of reasons and its threshold 0; the reasons go to
    ``alarm["contact_law"]``. A model without an alarm gets one made of this check. `seen`:
    the kinds of law the model was trained on (:func:`trained_law_kinds`), not judged; the
    alarm names them (``contact_law_trained_on``) so a reader knows what was not checked.
    Where the map was read through a mount left on it
    (:func:`~stiffnet.uncertainty.campaign_law.chain_left_on_map`) the check abstains and
    ``alarm["contact_law_unread"]`` says why; where only its exponent was not read
    (:func:`chain_left_on_exponent`), ``alarm["exponent_unread"]`` does: neither the exponent
    rule nor ``reference_penetration`` judged it. Where an exponent alarm fired on a map read
    with no chain, ``alarm["exponent_chain_unknown"]`` says what would resolve it
    (:func:`exponent_chain_unknown`).
    """
    t = unseen_law_thresholds()
    reasons = unseen_law_reasons(restoring_force, t, seen=seen)
    judged = ("exponent", "dissipation_gain", "law_shape")
    if all(restoring_force.get(k) is None for k in judged):
        return alarm  # the cross-check refused: nothing to judge
    if alarm is None:
        alarm = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}
    alarm = {**alarm, "scores": dict(alarm["scores"]), "thresholds": dict(alarm["thresholds"])}
    alarm["scores"]["contact_law"] = float(len(reasons))
    alarm["thresholds"]["contact_law"] = 0.0
    if seen:
        alarm["contact_law_trained_on"] = sorted(seen)
    left = chain_left_on_exponent(restoring_force, t)
    if not t.law_through_left_mount and chain_left_on_map(restoring_force):
        alarm["contact_law_unread"] = f"{left}: the contact law's shape is not read"
    elif left and not t.exponent_through_left_chain and restoring_force.get("exponent") is not None:
        ring = release_ring(restoring_force, t)
        what = "exponent and the within-impact curvature are" if ring else "exponent is"
        alarm["exponent_unread"] = f"{left}: the {what} not read as the law's"
    if reasons:
        alarm["fired"] = [*alarm["fired"], "contact_law"]
        alarm["flag"] = True
        alarm["contact_law"] = reasons
    note = exponent_chain_unknown(restoring_force, alarm["fired"], t)
    if note:
        alarm["exponent_chain_unknown"] = note
    alarm["message"] = alarm_message(alarm["fired"])
    return alarm


def exponent_chain_unknown(
    restoring_force: dict[str, Any], fired: list[str], t: UnseenLawThresholds
) -> str | None:
    """What an exponent alarm on a map read with no sensor chain cannot rule out (None: it
    can, or no exponent alarm fired).

    Where the exponent counted (:func:`exponent_reading`) above the linear band, fired the
    ``contact_law`` check or ``reference_penetration``, and the cross-check neither identified
    a chain nor was given one (``sensor`` absent or not applied), a sensor low-pass near the
    contact's band bends a linear contact's map the same way: bench_alarm's
    ``sensor_dynamics`` right answers #5, #7, #20 (seed offset 0, linear contacts behind
    low-passes at 0.16-0.17 fs of order 2-4) read 1.96, 1.39, 1.59 as recorded and 1.30,
    1.00, 1.15 with their data sheets, while the two-stage rig's wrong answers read 1.23-1.34
    with the same lack of a chain (docs/crosscheck.md). Where the low-pass rings after the
    release (:func:`release_ring`, as on those three) the exponent is not read and this note
    does not arise; a low-pass that leaves no such ring the record cannot tell from a
    stiffening law. The chain fit cannot settle it (forced on such maps it takes Hertz's and
    the two-stage law's bend for a low-pass); the accelerometer's data sheet can. The alarm
    stands; this says what would resolve it.
    """
    if "contact_law" not in fired and "reference_penetration" not in fired:
        return None
    if (restoring_force.get("sensor") or {}).get("applied"):
        return None
    reading = exponent_reading(restoring_force, t)
    linear_top = min(hi for _, hi in t.training_exponent_bands)
    if reading is None or not reading[0] > linear_top:
        return None
    return (
        f"the map was read as recorded, with no sensor chain identified or given: a sensor "
        f"low-pass near the contact's band bends a linear contact's map as this exponent "
        f"({reading[0]:.2f}) does, and the record cannot tell the two apart; give the "
        f"accelerometer's data sheet ({sensor_given()}) to read the law through its chain"
    )
