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
(:func:`serving.verdict.widened_interval`).

A campaign (:func:`campaign_reference_decision`, in ``evaluate``, where the manifest gives the
forcing amplitudes) has one rig and one convention, chosen by a lab among the depths its
impacts reach, not the training world's: each read power law's betas over the references from
the campaign's shallowest to its deepest median peak penetration widen the answer's interval
where they leave its class, and that interval is judged as ``class_unverified`` judges an
answer no reading confirms (``campaign_reference``). On the rig's power law (n 1.6, beta the
secant at 0.4 mm) behind a 250 Hz low-pass the training world's references left three answers
wrong and silent (beta 44-50 read 75-92 very_hard, 0.27-0.33 of their span outside it): the
campaign's impacts reach 0.094-1.26 model lengths, the rig's 0.4 mm lies at 0.28, and over
that range 0.43-0.56 of each interval lies outside very_hard. pydantic and the standard
library only: the predictor imports it.
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


#: The campaign check's name in an alarm's ``fired`` list.
CAMPAIGN_REFERENCE = "campaign_reference"


def read_penetration(
    restoring_force: dict[str, Any] | None,
    amplitude: float | None,
    thresholds: UnseenLawThresholds | None = None,
) -> float | None:
    """The impacts' median peak penetration in model lengths (the check's
    ``penetration_over_table`` times the forcing amplitude `amplitude`, model lengths) where the
    cross-check reads a clearly nonlinear power law (the rule of
    :func:`reference_penetration_span`); None elsewhere or without the amplitude."""
    rf = restoring_force or {}
    scale = rf.get("penetration_over_table")
    if not amplitude or not amplitude > 0 or not scale or not scale > 0 or not rf.get("beta"):
        return None
    t = thresholds or unseen_law_thresholds()
    reading = exponent_reading(rf, t)
    p_min = nonlinear_exponent_min(t.training_exponent_bands)
    if p_min is None or reading is None or reading[0] < p_min:
        return None
    return float(scale) * float(amplitude)


def campaign_reference_span(
    restoring_force: dict[str, Any] | None,
    penetration: float | None,
    references: tuple[float, float],
    thresholds: UnseenLawThresholds | None = None,
) -> list[float] | None:
    """The betas one recording allows over a campaign's reference penetrations
    `references` (model lengths): the cross-check's interval times
    ``(delta_ref / delta_rec)^(p - 1)`` at both ends, `penetration` its own ``delta_rec``
    (:func:`read_penetration`); None where that is None."""
    rf = restoring_force or {}
    interval = rf.get("beta_interval")
    reading = exponent_reading(rf, thresholds or unseen_law_thresholds())
    if penetration is None or not interval or reading is None:
        return None
    lo, hi = (float(v) for v in interval)
    if not 0 < lo <= hi:
        return None
    p = reading[0]
    return [lo * (references[0] / penetration) ** (p - 1.0),
            hi * (references[1] / penetration) ** (p - 1.0)]  # fmt: skip


def campaign_reference_decision(
    results: list[dict[str, Any]],
    amplitudes: list[float | None],
    model: dict[str, Any],
) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Rule: a campaign's stiffening contact, judged over the penetrations its own impacts reach.

    A campaign has one rig and one convention for a stiffening law's beta: the secant at a
    reference penetration the lab chose, which no record carries. A lab picks it among the
    penetrations its impacts reach, so over the campaign's read power laws the references run
    from the shallowest to the deepest median peak penetration (:func:`read_penetration`, in
    model lengths from the manifest's forcing amplitudes). Each such recording's betas over
    that range (:func:`campaign_reference_span`) are part of its answer's uncertainty: where
    they leave the model's class, the interval is widened to span them (said in a warning).
    The cross-check's close reading confirms no class there (its beta is the secant at the
    record's own depth, one convention among them), so the widened interval is judged as
    the ``class_unverified`` check judges an answer no reading confirms: where more than
    :attr:`~stiffnet.uncertainty.unverified_class.UnverifiedClassSettings.outside_share_min`
    of it (in log beta) lies outside the class, ``campaign_reference`` fires.

    Parameters
    ----------
    results : list of dict
        The predictor's results (``class``, ``beta_interval``, ``alarm``, ``restoring_force``).
    amplitudes : list of float or None
        Per result, the forcing amplitude in model lengths (the manifest's), None unknown.
    model : dict
        :func:`serving.verdict.model_facts`: ``class_names``, ``class_edges``.

    Returns
    -------
    results : list of dict
        Copies where the interval was widened (and ``alarm``, ``ood_flag`` set where the check
        fired), else the results themselves.
    decision : dict
        ``references`` (model lengths, None with fewer than two read), ``n_read``,
        ``n_widened``, ``n_fired`` and ``shares`` (per result: the widened interval's share
        outside the class, None where not judged).
    """
    from stiffnet.uncertainty.unverified_class import unverified_class_settings

    t = unseen_law_thresholds()
    depths = [read_penetration(r.get("restoring_force"), a, t)
              for r, a in zip(results, amplitudes, strict=True)]  # fmt: skip
    read = [d for d in depths if d is not None]
    decision: dict[str, Any] = {"references": None, "n_read": len(read), "n_widened": 0,
                                "n_fired": 0, "shares": [None] * len(results)}  # fmt: skip
    if len(read) < 2 or not max(read) > min(read):
        return results, decision
    refs = (min(read), max(read))
    decision["references"] = list(refs)
    names, low, high = class_ranges(model["class_names"], model.get("class_edges"))
    threshold = unverified_class_settings().outside_share_min
    out = []
    for i, (r, depth) in enumerate(zip(results, depths, strict=True)):
        span = campaign_reference_span(r.get("restoring_force"), depth, refs, t)
        interval = r.get("beta_interval")
        if span is None or not interval or r.get("class") not in names:
            out.append(r)
            continue
        k = names.index(r["class"])
        wide = [min(float(interval[0]), span[0]), max(float(interval[1]), span[1])]
        if not 0 < wide[0] < wide[1] or share_outside(*span, low[k], high[k]) == 0.0:
            out.append(r)
            continue
        share = share_outside(*wide, low[k], high[k])
        decision["shares"][i] = share
        alarm = with_rule_check(r.get("alarm"), CAMPAIGN_REFERENCE, share, threshold)
        fired = CAMPAIGN_REFERENCE in (alarm or {}).get("fired", [])
        decision["n_widened"] += 1
        decision["n_fired"] += fired
        out.append(_widened(r, alarm if fired else r.get("alarm"), wide, refs))
    return out, decision


def _widened(
    result: dict[str, Any], alarm: dict[str, Any] | None, wide: list[float], refs: tuple
) -> dict[str, Any]:
    """`result` with its interval `wide` (a warning says why) and `alarm`."""
    lo, hi = result["beta_interval"]
    said = (
        f"the beta interval [{lo:.3g}, {hi:.3g}] is widened to [{wide[0]:.3g}, {wide[1]:.3g}] "
        "to span the betas the contact law allows at the reference penetrations this "
        f"campaign's impacts reach ({refs[0]:.3g}-{refs[1]:.3g} model lengths): beta of a "
        "stiffening contact is a secant at a penetration the record does not carry"
    )
    flagged = bool((alarm or {}).get("flag"))
    return {**result, "alarm": alarm, "ood_flag": bool(result.get("ood_flag")) or flagged,
            "beta_interval": wide, "warnings": [*(result.get("warnings") or []), said]}  # fmt: skip
