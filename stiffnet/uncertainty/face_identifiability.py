r"""The alarm's face-identifiability check: beta behind a learned restraint face.

A model the loop retrained with a learned law that has a face of its own (``learned_contact``
with ``face_mass`` > 0: the stop is the tip of a beam, a plate on a mount) labels beta as the
contact's own stiffness, which acts in series with the face's support(s) of stiffness
``kappa_i`` (:mod:`stiffnet.effects.learned_contact`). The record carries the series
stiffness

.. math:: s = 1 / (1/\beta + c), \qquad c = \sum_i 1/\kappa_i ,

and its sensitivity to beta, ``d ln s / d ln beta = 1 / (1 + beta c)``, vanishes once beta
is several times ``1/c``: there the classes above some beta carry nearly one series stiffness
(the independent rig's beam: 5.91, 7.63, 8.39 at the class edges 15, 35, 60 and 8.80 at 90).
The training world draws the face's stiffness from its prior (the loop's jitter around the
discovered face, ``face_stiffness: [low, high]``), so the model cannot separate a stiff
contact behind a soft face from a softer contact behind a stiffer one.

The check (:func:`face_beta_interval`): the model's interval read as series stiffness at the
prior's central compliance, then back to beta with ``beta = 1 / (1/s - c)`` over the prior's
compliance range (``1/s <= c``: no upper bound within the training world; the top class
edge stands for it). That interval is what the signal allows; where most of it (in log beta)
lies outside the model's class (:func:`face_class_share`, above
:data:`FACE_CLASS_THRESHOLD`, a majority) the class is not determined by the record, the
check fires and the flagged answer's interval spans it (:func:`serving.verdict.widened_interval`).
A model without a learned face is not judged, nor one whose face scales with beta
(``face_stiffness_ratio`` > 0, :mod:`stiffnet.discovery.face_scaled`): there beta *is* the
series stiffness (the support ``r beta`` behind the contact ``beta r/(r - 1)``), which the
record carries, and the law's absolute ``face_stiffness`` is an unused default that would
otherwise be read as a support. For the predictor (no scikit-learn, torch or mlflow).
"""

from __future__ import annotations

import math
from typing import Any

from stiffnet.uncertainty.alarm_verdict import class_ranges, share_outside

#: The check's name in an alarm's ``fired`` list.
FACE_IDENTIFIABILITY = "face_identifiability"
#: It fires when more than half (in log beta) of what the face allows lies outside the model's
#: class: a majority, as ``class_contested``.
FACE_CLASS_THRESHOLD = 0.5


def prior_range(value: Any) -> tuple[float, float] | None:
    """A prior's ``[low, high]`` or single number as ``(low, high)``, None when not positive."""
    values = value if isinstance(value, list | tuple) else [value]
    try:
        nums = [float(v) for v in values]
    except (TypeError, ValueError):
        return None
    if not nums or not all(math.isfinite(v) and v > 0 for v in nums):
        return None
    return min(nums), max(nums)


def face_compliances(priors: dict[str, Any] | None) -> tuple[float, float, float] | None:
    """The learned face's support compliance ``sum 1/kappa_i`` over the training prior:
    ``(lowest, central, highest)``; None when the model's world has no learned face.

    The central one takes each mode's stiffness at the middle of its prior (the loop draws it
    around the discovered face); a mode with ``face*_mass`` 0 adds nothing. A face that
    scales with beta hides nothing behind its support (see the module notes): None.
    """
    for effect in (priors or {}).get("effects") or []:
        if not isinstance(effect, dict) or effect.get("name") != "learned_contact":
            continue
        if not effect.get("probability", 1.0) > 0:
            continue
        params = effect.get("params") or {}
        if prior_range(params.get("face_stiffness_ratio", 0.0)) is not None:
            return None
        low = mid = high = 0.0
        for mass, stiffness in (("face_mass", "face_stiffness"), ("face2_mass", "face2_stiffness")):
            m, k = prior_range(params.get(mass, 0.0)), prior_range(params.get(stiffness))
            if m is None or k is None:
                continue  # no such mode (mass 0) or no stiffness to read
            low, mid, high = low + 1 / k[1], mid + 2 / (k[0] + k[1]), high + 1 / k[0]
        return (low, mid, high) if high > 0 else None
    return None


def face_beta_interval(
    interval: list[float], compliances: tuple[float, float, float], top: float
) -> list[float]:
    """The betas behind the face that the model's interval allows (see the module notes):
    the interval as series stiffness at the central compliance, back to beta over the prior's
    compliance range; ``top`` where the series stiffness leaves beta unbounded above."""
    low_c, mid_c, high_c = compliances
    lo, hi = (float(v) for v in interval)
    s_lo, s_hi = 1.0 / (1.0 / lo + mid_c), 1.0 / (1.0 / hi + mid_c)
    beta_lo = 1.0 / (1.0 / s_lo - low_c)
    gap = 1.0 / s_hi - high_c
    beta_hi = 1.0 / gap if gap > 0 else math.inf
    return [min(beta_lo, lo), max(hi, min(beta_hi, max(top, hi)))]


def face_class_share(
    class_name: str,
    interval: list[float] | None,
    priors: dict[str, Any] | None,
    class_names: list[str],
    edges: Any,
) -> tuple[float, list[float]] | None:
    """Share (in log beta) of :func:`face_beta_interval` outside the model's class, and that
    interval; None without a learned face, an interval, a contact class or matching edges.
    The outer classes are open-ended, as in the other class checks
    (:func:`~stiffnet.uncertainty.alarm_verdict.class_ranges`)."""
    compliances = face_compliances(priors)
    names, low, high = class_ranges(class_names, edges)
    if compliances is None or not interval or class_name not in names:
        return None
    lo_m, hi_m = (float(v) for v in interval)
    if not 0 < lo_m <= hi_m:
        return None
    wide = face_beta_interval([lo_m, hi_m], compliances, float(edges[-1]))
    lo, hi = wide
    if not hi > lo:
        return 0.0, wide
    i = names.index(class_name)
    return share_outside(lo, hi, low[i], high[i]), wide
