"""A campaign's contact law, judged on all its recordings at once.

The predictor's unseen-law check (``contact_law``, :mod:`stiffnet.uncertainty.unseen_law`)
judges each recording alone, with thresholds set so that the training world's laws
(linear, Kelvin-Voigt, Hertz, behind the sensor chains of the priors) rarely fire it: 0-2
recordings in 24 on each such set. On a rig whose law the model never saw it fires on
many recordings but not on all of them: a recording whose impacts stay short of a knee,
or whose map bends as smoothly as a sensor chain's, reads like the training world, and
the model's wrong answers there stay silent (docs/crosscheck.md: 4-6 of 24 on the
robustness sets' Hunt-Crossley and power laws).

A campaign's recordings share one rig, hence one contact law and one restraint. Where more
of them fire the check (or the ``restraint_dynamics`` check, a restraint that rings within
its contacts: :data:`LAW_CHECKS`) than the training world's rate allows, the law is outside
the model's world for every recording, including those whose own map could not show it: the
campaign's ``campaign_law`` check fires on all of them. The rule is a one-sided binomial test of the
count that fired among those the check could judge (a refused map judges nothing) against
the in-world rate :attr:`CampaignLawThresholds.in_world_rate`, at level
:attr:`CampaignLawThresholds.level` (``configs/alarm/campaign_law.yaml``): a campaign of
a few recordings cannot reach it, as it should not.

Numpy/scipy only: the predictor's campaign commands (``evaluate``, ``predict-batch``)
import it.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
from typing import Any

from pydantic import BaseModel, ConfigDict, Field
from scipy import stats

from stiffnet.uncertainty.alarm_verdict import alarm_message

#: The check's name in an alarm's ``fired`` list.
CAMPAIGN_LAW = "campaign_law"
#: The per-recording checks whose firing counts: the contact law's own
#: (:mod:`~stiffnet.uncertainty.unseen_law`) and a restraint that rings within its contacts
#: (:mod:`~stiffnet.uncertainty.restraint_dynamics`), which reads a map the contact-law check
#: judges.
LAW_CHECKS = ("contact_law", "restraint_dynamics")
THRESHOLDS_CONFIG = "alarm/campaign_law.yaml"


class CampaignLawThresholds(BaseModel):
    """The campaign rule's settings (``configs/alarm/campaign_law.yaml``)."""

    model_config = ConfigDict(extra="forbid")

    #: Share of recordings of a training-world rig on which ``contact_law`` fires.
    in_world_rate: float = Field(0.1, gt=0.0, lt=1.0)
    #: Probability, under that rate, of the count that fired or more, below which the
    #: campaign's law is outside the model's world.
    level: float = Field(1e-3, gt=0.0, lt=1.0)


@lru_cache(maxsize=1)
def campaign_law_thresholds() -> CampaignLawThresholds:
    """The shipped settings: ``configs/alarm/campaign_law.yaml``, else the defaults."""
    from stiffnet.config import shipped_settings

    return shipped_settings(CampaignLawThresholds, THRESHOLDS_CONFIG)


def contact_law_fired(alarm: dict[str, Any] | None) -> tuple[bool, bool]:
    """Whether a recording's alarm judged its contact law (the check ran on a readable
    map) and whether a check of :data:`LAW_CHECKS` fired."""
    alarm = alarm or {}
    judged = "contact_law" in (alarm.get("scores") or {})
    return judged, judged and law_check_fired(alarm.get("fired") or [])


def law_check_fired(fired: Sequence[str]) -> bool:
    """Whether any check of :data:`LAW_CHECKS` is among an alarm's `fired` checks."""
    return any(name in fired for name in LAW_CHECKS)


def campaign_law_decision(
    judged: Sequence[bool],
    fired: Sequence[bool],
    thresholds: CampaignLawThresholds | None = None,
) -> dict[str, Any]:
    """Rule: is the campaign's contact law outside the model's world?

    Parameters
    ----------
    judged, fired : sequence of bool
        Per recording: the ``contact_law`` check could judge its map; it fired.
    thresholds : CampaignLawThresholds, optional
        Default: the shipped ones.

    Returns
    -------
    dict
        ``flag``, ``n_judged``, ``n_fired``, ``p_value`` (the binomial tail under the
        in-world rate; None with nothing judged), ``in_world_rate``, ``level`` and
        ``message``.
    """
    t = thresholds or campaign_law_thresholds()
    n = int(sum(bool(j) for j in judged))
    m = int(sum(bool(j) and bool(f) for j, f in zip(judged, fired, strict=True)))
    p = float(stats.binom.sf(m - 1, n, t.in_world_rate)) if n else None
    flag = p is not None and p < t.level
    if flag:
        message = (
            f"the contact law fired on {m} of the {n} recordings it could judge, more than "
            f"a law of the training world does ({t.in_world_rate:.0%}; p = {p:.1e}): the "
            "campaign's rig is outside the model's world, every recording included"
        )
    else:
        message = f"the contact law fired on {m} of the {n} recordings it could judge"
    return {"flag": flag, "n_judged": n, "n_fired": m, "p_value": p,
            "in_world_rate": t.in_world_rate, "level": t.level, "message": message}  # fmt: skip


def with_campaign_law(result: dict[str, Any], decision: dict[str, Any]) -> dict[str, Any]:
    """A copy of a prediction `result` with the campaign's ``campaign_law`` check fired in
    its alarm (``ood_flag`` set) where `decision` flags the campaign; else `result`."""
    if not decision["flag"]:
        return result
    alarm = dict(result.get("alarm") or {"flag": False, "fired": [], "scores": {},
                                         "thresholds": {}})  # fmt: skip
    alarm["fired"] = [*alarm.get("fired", []), CAMPAIGN_LAW]
    alarm["flag"] = True
    alarm[CAMPAIGN_LAW] = decision["message"]
    alarm["message"] = alarm_message(alarm["fired"])
    return {**result, "alarm": alarm, "ood_flag": True}


def campaign_law_alarms(
    results: Sequence[dict[str, Any]], thresholds: CampaignLawThresholds | None = None
) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """The campaign's predictions with :func:`with_campaign_law` applied, and the decision
    (:func:`campaign_law_decision` over their alarms)."""
    reads = [contact_law_fired(r.get("alarm")) for r in results]
    decision = campaign_law_decision([j for j, _ in reads], [f for _, f in reads], thresholds)
    return [with_campaign_law(r, decision) for r in results], decision
