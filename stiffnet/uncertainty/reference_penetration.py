r"""The alarm's reference-penetration check: beta of a stiffening contact is a convention.

A contact whose force grows as a power of the penetration (``hertz_contact``: ``F = k_h
delta^p``, p = 3/2) has no one stiffness; its label beta is the secant stiffness at a
reference penetration ``delta_ref`` (:mod:`stiffnet.effects.hertz_contact`), ``beta = k_h
delta_ref^(p-1)``. The record carries ``k_h`` only: the restoring-force cross-check reads the
secant at the impacts' own median peak penetration ``delta_rec``, and the model, which sees
the record without its gain, reads beta near there too. The training world draws
``delta_ref`` from its prior (0.1-2.0 model lengths for the shipped models), independently of
the rig, so the betas the record allows are

.. math:: \beta = \beta_\mathrm{check} \, (\delta_\mathrm{ref} / \delta_\mathrm{rec})^{p-1},
   \qquad \delta_\mathrm{ref} \in \text{the prior}.

``delta_rec`` in the model's length units: the record has no unit (any gain), but the
cross-check reads ``delta_rec`` over the table's displacement amplitude, a ratio within one
map (``penetration_over_table``), and the table's amplitude is the forcing amplitude ``a``
in model units (docs/simulator.md). The predictor is not told ``a`` (only ``fs`` and
``f_n``), so the check takes ``a`` over the training world's prior (the card's sweep):
``delta_rec`` in ``penetration_over_table x [a_low, a_high]``. Known ``a``, the span would be
the reference prior's alone.

The check (:func:`reference_penetration_span`) applies where the cross-check reads a clearly
nonlinear power law: an exponent at or above the lowest training exponent band above the
linear one (the Hertz band of ``configs/alarm/unseen_law.yaml``, or beyond) from a law
explaining ``exponent_min_r2`` of the contact force, or read with an onset per impact where
that law does not (:func:`~stiffnet.uncertainty.unseen_law.exponent_reading`), on a model
whose training world draws Hertz contacts. An exponent read through a sensor chain the
cross-check left on the map (:func:`~stiffnet.uncertainty.unseen_law.chain_left_on_exponent`:
a chain shows in the record but none was undone, or low-passes of the priors stay
unexcluded) is partly the chain's low-pass, which bends a linear law's map into the Hertz band,
so it says nothing of a reference penetration and the check does not apply (the alarm's
``exponent_unread`` says why). Where more than half (in log beta) of the span
lies outside the model's class (:attr:`ReferencePenetrationSettings.outside_share_min`, the
majority ``class_contested`` and ``face_identifiability`` use, not a fitted level) the class is not
determined by the record: the check fires and the flagged answer's interval spans the span
(:func:`serving.verdict.widened_interval`). pydantic and the standard library only: the
predictor imports it.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from stiffnet.uncertainty.alarm_verdict import class_ranges, share_outside, with_rule_check
from stiffnet.uncertainty.face_identifiability import prior_range
from stiffnet.uncertainty.unseen_law import (
    UnseenLawThresholds,
    exponent_reading,
    unseen_law_thresholds,
)

#: The check's name in an alarm's ``fired`` list.
REFERENCE_PENETRATION = "reference_penetration"
#: The shipped settings (``configs/alarm/reference_penetration.yaml``), relative to the package.
SETTINGS_CONFIG = "alarm/reference_penetration.yaml"
#: The training world's effect whose beta is a secant at a reference penetration.
HERTZ_EFFECT = "hertz_contact"


class ReferencePenetrationSettings(BaseModel):
    """Settings of the ``reference_penetration`` check
    (``configs/alarm/reference_penetration.yaml``)."""

    model_config = ConfigDict(extra="forbid")

    #: Share (in log beta) of the betas the record allows outside the model's class above
    #: which the class is not determined by the record: a majority.
    outside_share_min: float = Field(0.5, ge=0.0, lt=1.0)


@lru_cache(maxsize=1)
def reference_penetration_settings() -> ReferencePenetrationSettings:
    """The shipped settings: ``configs/alarm/reference_penetration.yaml``, else the defaults."""
    from stiffnet.config import shipped_settings

    return shipped_settings(ReferencePenetrationSettings, SETTINGS_CONFIG)


def nonlinear_exponent_min(bands: list[tuple[float, float]]) -> float | None:
    """The lowest exponent of a clearly nonlinear law: the lower edge of the lowest training
    exponent band that does not hold the linear law's 1; None where every band does."""
    edges = [float(lo) for lo, hi in bands if not lo <= 1.0 <= hi]
    return min(edges) if edges else None


def training_ranges(
    priors: dict[str, Any] | None,
) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """The training world's reference penetrations and forcing amplitudes (model length units)
    as ``((ref_low, ref_high), (a_low, a_high))``; None where it draws no Hertz contact or
    gives no amplitude."""
    amplitude = prior_range(((priors or {}).get("sweep") or {}).get("amplitude"))
    for effect in (priors or {}).get("effects") or []:
        if not isinstance(effect, dict) or effect.get("name") != HERTZ_EFFECT:
            continue
        if not effect.get("probability", 1.0) > 0:
            continue
        ref = prior_range((effect.get("params") or {}).get("reference_penetration"))
        return None if ref is None or amplitude is None else (ref, amplitude)
    return None


def reference_penetration_span(
    restoring_force: dict[str, Any] | None,
    priors: dict[str, Any] | None,
    thresholds: UnseenLawThresholds | None = None,
) -> list[float] | None:
    """The betas the record allows over the training world's reference penetrations (see the
    module notes): the cross-check's interval times ``(delta_ref / delta_rec)^(p - 1)`` at
    both ends of the ratio's range; None where the check does not apply (no clearly nonlinear
    close-fitting law, an exponent read through a chain left on the map, no penetration
    scale, or a training world without Hertz contacts). `thresholds`: those that read the
    exponent (:func:`~stiffnet.uncertainty.unseen_law.exponent_reading`; default the shipped
    ones)."""
    rf = restoring_force or {}
    ranges = training_ranges(priors)
    interval, scale = rf.get("beta_interval"), rf.get("penetration_over_table")
    if ranges is None or not interval or not scale:
        return None
    t = thresholds or unseen_law_thresholds()
    reading = exponent_reading(rf, t)
    p_min = nonlinear_exponent_min(t.training_exponent_bands)
    if p_min is None or reading is None or not (reading[0] >= p_min and scale > 0):
        return None
    p = reading[0]
    lo, hi = (float(v) for v in interval)
    if not 0 < lo <= hi:
        return None
    (ref_lo, ref_hi), (a_lo, a_hi) = ranges
    low_ratio, high_ratio = ref_lo / (scale * a_hi), ref_hi / (scale * a_lo)
    return [lo * low_ratio ** (p - 1.0), hi * high_ratio ** (p - 1.0)]


def reference_penetration_share(
    class_name: str,
    restoring_force: dict[str, Any] | None,
    priors: dict[str, Any] | None,
    class_names: list[str],
    edges: Any,
    thresholds: UnseenLawThresholds | None = None,
) -> float | None:
    """Share (in log beta) of :func:`reference_penetration_span` outside the model's class;
    None where the span does not apply, for ``no_contact`` or edges that do not match the
    classes. The outer classes are open-ended, as in the other class checks
    (:func:`~stiffnet.uncertainty.alarm_verdict.class_ranges`). `thresholds` as in
    :func:`reference_penetration_span`."""
    span = reference_penetration_span(restoring_force, priors, thresholds)
    names, low, high = class_ranges(class_names, edges)
    if span is None or class_name not in names:
        return None
    lo, hi = span
    i = names.index(class_name)
    if not hi > lo:
        return 0.0 if low[i] <= lo <= high[i] else 1.0
    return share_outside(lo, hi, low[i], high[i])


def with_reference_penetration_check(
    alarm: dict[str, Any] | None,
    class_name: str,
    restoring_force: dict[str, Any] | None,
    priors: dict[str, Any] | None,
    class_names: list[str],
    edges: Any,
) -> dict[str, Any] | None:
    """The alarm with the ``reference_penetration`` check added
    (:func:`reference_penetration_share` against
    :attr:`ReferencePenetrationSettings.outside_share_min`)."""
    share = reference_penetration_share(class_name, restoring_force, priors, class_names, edges)
    threshold = reference_penetration_settings().outside_share_min
    return with_rule_check(alarm, REFERENCE_PENETRATION, share, threshold)
