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
of them read a law outside the training world than the training world's rate allows (the
checks of :attr:`CampaignLawThresholds.law_checks`: the contact law's own, a restraint that
rings within its contacts, and contacts that outlast twice the half period of the law they
fit), the law is outside the model's world for every recording, including those whose own
map could not show it: the campaign's ``campaign_law`` check fires on all of them. The rule
is a one-sided binomial test of the count that fired among the recordings whose law was
read (:func:`contact_law_fired`) against the in-world rate
:attr:`CampaignLawThresholds.in_world_rate`, at level :attr:`CampaignLawThresholds.level`
(``configs/alarm/campaign_law.yaml``): a campaign of a few recordings cannot reach it, as
it should not.

The contact-duration reading counts because of where it fires: the restoring-force
cross-check refuses a map whose contacts last over twice the half period of its fitted law
(``contact_duration``), and a refused map scores no ``contact_law``. A two-stage restraint
behind a mounted accelerometer is refused so on a third of its recordings (the soft first
stage adds its own time to every contact, the mount's ringing hides its force from the
stage and soft-first-stage rules), and a rule that counted only the maps it could judge
then missed the campaign; no recording of the training world's sets is refused so.

A contact-law reading through a chain the map could not undo is no reading of the law
(:func:`chain_left_on_map`): where the record shows a mount's ringing (the cross-check
divided it out, ``resonance_hz``) but the chain it belongs to was not undone (no chain
fitted, the law fitting well enough as recorded, or a fitted one rejected), the map still
carries the chain's low-pass and whatever of the mount the division missed, and the
exponent and curvature rules read that chain's bend of the pulse (the training world's
sensor sets: exponents 1.23-2.01 and curvature gains 0.17-0.49 on such maps of right
answers). Such a recording's ``contact_law`` check neither counts as read nor as fired; a
counted check that reads the contacts' duration or the restraint still counts. The training
world's sensor sets put 7 such maps, 5 of them firing, among the 20 read recordings of one
campaign (sensor_dynamics at ``--seed-offset`` 3000, flagged at p 7e-6 by a count that held
them; without them 5 of 13, p 6.5e-3); no firing map of an unseen-law set is such a map
(the rig's two-stage law behind a mount fires through its undone chain). Behind the
priors' chains the rules still fire above the in-world rate (docs/crosscheck.md).

A map the cross-check refused because no law it fits explains the contact force (below
:data:`~stiffnet.restoring_force.estimate.MIN_CONTACT_R2`, :func:`contact_unexplained`)
counts as read and fired too (``contact_unexplained``): a refusal is no agreement, and where
the contact force follows no law the cross-check can fit, nothing physical checks the
model's answer. A restraint with its own mass behind a high-pass (a heavy face at 6-15 f_n)
is refused so on most recordings ("the contact law explains 3-12 %"): the model read beta
23-28 for 35-88 there, 8 of 24 wrong, with no alarm, because a count over the maps the
contact-law check judged had no map to count. None of the rig's ideal, mounted or
damped-contact campaigns has such a refusal (0 of 72 recordings). A refusal for the
sensor's band (:data:`~stiffnet.uncertainty.alarm_verdict.SENSOR_REFUSAL_WORDS`) is the
``chain_refusal`` check's and does not count.

Numpy/scipy only: the predictor's campaign commands (``evaluate``, ``predict-batch``)
import it.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, field_validator
from scipy import stats

from stiffnet.restoring_force.estimate import MIN_CONTACT_R2
from stiffnet.uncertainty.alarm_verdict import SENSOR_REFUSAL_WORDS, alarm_message

#: The check's name in an alarm's ``fired`` list.
CAMPAIGN_LAW = "campaign_law"
#: The per-recording checks whose firing counts: the contact law's own
#: (:mod:`~stiffnet.uncertainty.unseen_law`), a restraint that rings within its contacts
#: (:mod:`~stiffnet.uncertainty.restraint_dynamics`), which reads a map the contact-law check
#: judges, and contacts that last over twice the half period of the law they fit
#: (``contact_duration``, :func:`stiffnet.uncertainty.alarm_verdict.contact_duration_excess`),
#: which reads a map the cross-check refused for it.
#: ``contact_unexplained``: the cross-check refused the map because no law it fits explains
#: the contact force (:func:`contact_unexplained`); no alarm check of its own, the campaign
#: reads it from the recording's cross-check.
LAW_CHECKS = ("contact_law", "restraint_dynamics", "contact_duration", "contact_unexplained")
#: The counted reading that is not an alarm check.
CONTACT_UNEXPLAINED = "contact_unexplained"
#: What each check of :data:`LAW_CHECKS` saw, for the campaign's message.
LAW_CHECK_WORDS = {
    "contact_law": "a contact law the training world lacks",
    "restraint_dynamics": "a restraint that rings within its contacts",
    "contact_duration": "contacts outlasting twice the half period of the law they fit",
    "contact_unexplained": "a contact force no law the restoring-force cross-check fits "
    "explains (it refused: the model's answer is checked by nothing physical)",
}
THRESHOLDS_CONFIG = "alarm/campaign_law.yaml"


class CampaignLawThresholds(BaseModel):
    """The campaign rule's settings (``configs/alarm/campaign_law.yaml``)."""

    model_config = ConfigDict(extra="forbid")

    #: Share of recordings of a training-world rig on which ``contact_law`` fires.
    in_world_rate: float = Field(0.1, gt=0.0, lt=1.0)
    #: Probability, under that rate, of the count that fired or more, below which the
    #: campaign's law is outside the model's world.
    level: float = Field(5e-3, gt=0.0, lt=1.0)
    #: The per-recording checks whose firing counts (:data:`LAW_CHECKS`, or fewer).
    law_checks: list[str] = Field(default_factory=lambda: list(LAW_CHECKS))
    #: Whether a ``contact_law`` reading through a chain the map could not undo
    #: (:func:`chain_left_on_map`) counts; false: it is no reading of the law.
    count_chain_left_on_map: bool = False

    @field_validator("law_checks")
    @classmethod
    def _known_checks(cls, value: list[str]) -> list[str]:
        unknown = sorted(set(value) - set(LAW_CHECKS))
        if unknown:
            raise ValueError(f"law_checks: unknown checks {unknown} (known: {list(LAW_CHECKS)})")
        return value


@lru_cache(maxsize=1)
def campaign_law_thresholds() -> CampaignLawThresholds:
    """The shipped settings: ``configs/alarm/campaign_law.yaml``, else the defaults."""
    from stiffnet.config import shipped_settings

    return shipped_settings(CampaignLawThresholds, THRESHOLDS_CONFIG)


def chain_left_on_map(restoring_force: dict[str, Any] | None) -> bool:
    """Rule: the restoring-force map was read through a sensor chain it could not undo: the
    record shows a mount's ringing (``resonance_hz``, divided out) and no chain was undone
    (``sensor`` absent or not ``applied``). The law's shape read there is partly the chain's;
    the per-recording ``contact_law`` check abstains there too
    (:attr:`~stiffnet.uncertainty.unseen_law.UnseenLawThresholds.law_through_left_mount`)."""
    rf = restoring_force or {}
    return rf.get("resonance_hz") is not None and not (rf.get("sensor") or {}).get("applied")


def contact_unexplained(restoring_force: dict[str, Any] | None) -> bool:
    """Rule: the restoring-force cross-check refused the map because the contact law it fits
    explains less than :data:`~stiffnet.restoring_force.estimate.MIN_CONTACT_R2` of the
    contact force (no beta, ``contact_r2`` below the floor), not for the sensor's band
    (:data:`~stiffnet.uncertainty.alarm_verdict.SENSOR_REFUSAL_WORDS`, the
    ``chain_refusal`` check's). Such a refusal says the contact follows no law the
    cross-check knows: it leaves the model's answer unverified, not confirmed."""
    rf = restoring_force or {}
    r2 = rf.get("contact_r2")
    if rf.get("beta") is not None or r2 is None or not r2 < MIN_CONTACT_R2:
        return False
    return SENSOR_REFUSAL_WORDS not in str(rf.get("reason") or "")


def contact_law_fired(
    alarm: dict[str, Any] | None,
    thresholds: CampaignLawThresholds | None = None,
    restoring_force: dict[str, Any] | None = None,
) -> tuple[bool, bool]:
    """Whether a recording's law was read and whether a check of the counted
    :attr:`CampaignLawThresholds.law_checks` fired: read where the ``contact_law`` check
    judged its map, or where a counted check fired on a map it could not judge (the
    cross-check refused contacts that outlast their law, or a contact force no law it fits
    explains: :func:`contact_unexplained`). The ``contact_law`` check's own
    reading does not count on a map read through a chain it could not undo
    (:func:`chain_left_on_map` of the recording's `restoring_force`), unless
    :attr:`CampaignLawThresholds.count_chain_left_on_map`."""
    judged, counted = _law_read(alarm, thresholds or campaign_law_thresholds(), restoring_force)
    return judged, bool(counted)


def _law_read(
    alarm: dict[str, Any] | None, t: CampaignLawThresholds, restoring_force: dict[str, Any] | None
) -> tuple[bool, list[str]]:
    """:func:`contact_law_fired`'s reading, with the counted checks that fired."""
    alarm = alarm or {}
    fired = law_checks_fired(alarm.get("fired") or [], t)
    own = "contact_law" in (alarm.get("scores") or {})
    if own and not t.count_chain_left_on_map and chain_left_on_map(restoring_force):
        own, fired = False, [name for name in fired if name != "contact_law"]
    if CONTACT_UNEXPLAINED in t.law_checks and contact_unexplained(restoring_force):
        fired = [*fired, CONTACT_UNEXPLAINED]
    return own or bool(fired), fired


def law_checks_fired(
    fired: Sequence[str], thresholds: CampaignLawThresholds | None = None
) -> list[str]:
    """The counted checks (:attr:`CampaignLawThresholds.law_checks`) among an alarm's
    `fired` checks."""
    counted = (thresholds or campaign_law_thresholds()).law_checks
    return [name for name in counted if name in fired]


def campaign_law_decision(
    judged: Sequence[bool],
    fired: Sequence[bool],
    thresholds: CampaignLawThresholds | None = None,
    seen: Sequence[Sequence[str]] | None = None,
) -> dict[str, Any]:
    """Rule: is the campaign's contact law outside the model's world?

    Parameters
    ----------
    judged, fired : sequence of bool
        Per recording: its law was read (:func:`contact_law_fired`); a counted check fired.
    thresholds : CampaignLawThresholds, optional
        Default: the shipped ones.
    seen : sequence of sequence of str, optional
        Per recording, the counted checks that fired (:func:`law_checks_fired`): the message
        then says how many recordings each one fired on.

    Returns
    -------
    dict
        ``flag``, ``n_judged``, ``n_fired``, ``p_value`` (the binomial tail under the
        in-world rate; None with nothing judged), ``in_world_rate``, ``level``, ``by_check``
        (recordings per counted check, where `seen` was given) and ``message``.
    """
    t = thresholds or campaign_law_thresholds()
    n = int(sum(bool(j) for j in judged))
    m = int(sum(bool(j) and bool(f) for j, f in zip(judged, fired, strict=True)))
    p = float(stats.binom.sf(m - 1, n, t.in_world_rate)) if n else None
    flag = p is not None and p < t.level
    by_check = {name: sum(name in s for s in seen) for name in t.law_checks} if seen else {}
    what = "; ".join(f"{LAW_CHECK_WORDS[k]} on {v}" for k, v in by_check.items() if v)
    count = f"the contact law read outside the training world on {m} of the {n} recordings " \
        "whose law was read" + (f" ({what})" if what else "")  # fmt: skip
    if flag:
        message = (
            f"{count}, more than a law of the training world does ({t.in_world_rate:.0%}; "
            f"p = {p:.1e}): the campaign's rig is outside the model's world, every recording "
            "included"
        )
        if by_check.get(CONTACT_UNEXPLAINED):
            message += (
                "; where the cross-check refused, no physical reading verifies the model's "
                "beta or class: they are its guess on a contact it was not trained for"
            )
    else:
        message = count
    return {"flag": flag, "n_judged": n, "n_fired": m, "p_value": p,
            "in_world_rate": t.in_world_rate, "level": t.level, "by_check": by_check,
            "message": message}  # fmt: skip


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
    t = thresholds or campaign_law_thresholds()
    reads = [_law_read(r.get("alarm"), t, r.get("restoring_force")) for r in results]
    seen = [counted for _, counted in reads]
    decision = campaign_law_decision([j for j, _ in reads], [bool(c) for c in seen], t, seen)
    return [with_campaign_law(r, decision) for r in results], decision
