"""The verdict behind one answer: the rule checks on the model's answer and the interval behind
an alarm, in one place for ``predict`` and the stiffness log.

The model's own checks (embedding, ambiguity, beta uncertainty, class edge:
:func:`stiffnet.uncertainty.alarm_verdict.alarm_verdict`) are evaluated by the caller on its
windows. :func:`rule_checks` adds the rule checks: the model's class against its own beta, the
restoring-force cross-check against the model (disjoint intervals, another class, a class
neither reading places beta in, stretched contacts, a refusal behind a chain outside the
priors), a class near an edge that no close reading checks (its threshold set on draws the
benchmark does not score), beta behind a learned face the record cannot resolve, beta of a
stiffening contact at reference penetrations the record does not carry, a contact
law the training world lacks, a restraint that rings within its contacts, and the identified
sensor chain against the training priors.
:func:`widened_interval` is the interval a flagged answer reports
(:func:`stiffnet.uncertainty.conformal.interval_behind_alarm`) and the warning saying so.
"""

from __future__ import annotations

from typing import Any

from serving.restoring_force_check import sensor_outside_priors, with_sensor_check
from stiffnet.uncertainty.alarm_verdict import (
    RESTORING_FORCE_MIN_R2,
    class_beta_gap,
    restoring_force_gap,
    with_chain_refusal_check,
    with_class_beta_check,
    with_class_contested_check,
    with_restoring_force_check,
    with_restoring_force_checks,
    with_rule_check,
    with_sensor_fit_check,
)
from stiffnet.uncertainty.conformal import interval_behind_alarm
from stiffnet.uncertainty.face_identifiability import (
    FACE_CLASS_THRESHOLD,
    FACE_IDENTIFIABILITY,
    face_class_share,
)
from stiffnet.uncertainty.outvoted_class import with_outvoted_class_check
from stiffnet.uncertainty.reference_penetration import (
    reference_penetration_span,
    with_reference_penetration_check,
)
from stiffnet.uncertainty.restraint_dynamics import with_restraint_dynamics_check
from stiffnet.uncertainty.unseen_law import trained_law_kinds, with_unseen_law_check
from stiffnet.uncertainty.unverified_class import with_unverified_class_check


def model_facts(predictor: Any) -> dict[str, Any]:
    """What the rule checks read of a loaded model: its classes, class edges and the training
    world's priors (the card's ``data.priors``)."""
    return {
        "class_names": predictor.class_names,
        "class_edges": predictor.metadata.get("class_edges"),
        "priors": (predictor.model.card.get("data") or {}).get("priors"),
    }


def rule_checks(
    alarm: dict[str, Any] | None,
    class_name: str,
    interval: list[float] | None,
    restoring_force: dict[str, Any] | None,
    model: dict[str, Any],
    fs_hz: float,
    natural_frequency_hz: float,
    head_class: str | None = None,
    sensor_read: dict | None = None,
    geometric_class: str | None = None,
) -> dict[str, Any] | None:
    """The alarm with the rule checks added to the model's own (`alarm`, None without one).

    Parameters
    ----------
    alarm : dict or None
        The model's checks on these windows (``flag``, ``fired``, ``scores``, ``thresholds``).
    class_name : str
        The class answered.
    interval : list of float or None
        The beta interval answered.
    restoring_force : dict or None
        The restoring-force cross-check on the same samples
        (:func:`serving.restoring_force_check.restoring_force_check`); None when none ran.
    model : dict
        ``class_names``, ``class_edges`` and ``priors`` (the card's ``data.priors``).
    fs_hz, natural_frequency_hz : float
    head_class : str, optional
        The class head's own class where another rule answered (``class_beta`` compares the
        two heads); the class answered by default.
    sensor_read : dict, optional
        The chain as the model read it where the predictor undid stages of it
        (:func:`serving.chain_undo.chain_as_read`): the ``sensor`` check judges that one
        against the priors. Default: the identified chain.
    geometric_class : str, optional
        The geometric cross-check's class on the same record: with the restoring-force
        class, the two physical readings ``class_outvoted`` weighs against the model's class
        (None: the check does not apply).
    """
    names, edges = model["class_names"], model.get("class_edges")
    gap = class_beta_gap(head_class or class_name, interval, names, edges)
    alarm = with_class_beta_check(alarm, gap)
    face = face_class_share(class_name, interval, model.get("priors"), names, edges)
    alarm = with_rule_check(alarm, FACE_IDENTIFIABILITY, None if face is None else face[0],
                            FACE_CLASS_THRESHOLD)  # fmt: skip
    if restoring_force is None:
        return alarm
    judged = restoring_force
    if restoring_force.get("reading_interval"):
        judged = {**restoring_force, "beta_interval": restoring_force["reading_interval"]}
    gap = restoring_force_gap(interval, judged["beta_interval"], judged.get("contact_r2"))
    alarm = with_restoring_force_check(alarm, gap)
    alarm = with_restoring_force_checks(alarm, class_name, judged, names, edges)
    alarm = with_class_contested_check(alarm, class_name, interval, judged, names, edges)
    alarm = with_unverified_class_check(alarm, class_name, interval, judged, names, edges)
    alarm = with_outvoted_class_check(alarm, class_name, interval, geometric_class,
                                      judged, names, edges)  # fmt: skip
    priors = model.get("priors")
    alarm = with_reference_penetration_check(alarm, class_name, restoring_force, priors, names,
                                             edges)  # fmt: skip
    seen = trained_law_kinds(priors)
    alarm = with_unseen_law_check(alarm, restoring_force, seen)
    alarm = with_restraint_dynamics_check(alarm, restoring_force, seen)
    sensor = restoring_force.get("sensor")
    alarm = with_sensor_fit_check(alarm, sensor, priors, fs_hz)
    alarm = with_chain_refusal_check(alarm, restoring_force, priors, fs_hz)
    read = sensor if sensor_read is None else sensor_read
    outside = sensor_outside_priors(read, priors, fs_hz, natural_frequency_hz)
    return with_sensor_check(alarm, outside)


def widened_interval(
    interval: list[float] | None,
    restoring_force: dict[str, Any] | None,
    model: dict[str, Any] | None = None,
) -> tuple[list[float] | None, str | None]:
    """A flagged answer's beta interval, spanning a close-fitting restoring-force interval and,
    for a model trained behind a learned face (`model`: :func:`model_facts`), the betas the
    face allows over it (:func:`~stiffnet.uncertainty.face_identifiability.face_beta_interval`),
    and on a clearly nonlinear contact law the betas its reference penetrations allow
    (:func:`~stiffnet.uncertainty.reference_penetration.reference_penetration_span`), and the
    warning that says so (None when it is not wider)."""
    wide = interval
    if restoring_force is not None:
        wide = interval_behind_alarm(
            interval,
            restoring_force["beta_interval"],
            restoring_force.get("contact_r2"),
            RESTORING_FORCE_MIN_R2,
        )
    behind_face = _face_allowed(interval, model)
    if wide and behind_face:
        wide = [min(wide[0], behind_face[0]), max(wide[1], behind_face[1])]
    at_references = reference_penetration_span(restoring_force, (model or {}).get("priors"))
    if wide and at_references:
        wide = [min(wide[0], at_references[0]), max(wide[1], at_references[1])]
    if not (wide and interval and wide != list(interval)):
        return wide, None
    why = "the restoring-force interval"
    if behind_face and list(behind_face) != list(interval):
        why = "the betas the learned face allows (beta is barely identifiable behind it)"
    elif at_references:
        why = (
            "the betas the contact law allows at the training world's reference penetrations "
            "(beta is a secant at a penetration the record does not carry)"
        )
    return wide, (
        f"the beta interval [{interval[0]:.3g}, {interval[1]:.3g}] is widened to "
        f"[{wide[0]:.3g}, {wide[1]:.3g}] to span {why}: the alarm "
        "says the model's calibration does not hold for this recording"
    )


def _face_allowed(interval: list[float] | None, model: dict[str, Any] | None) -> list[float] | None:
    """The betas a learned face allows over the model's interval (None without a face)."""
    if not model or not interval:
        return None
    edges = model.get("class_edges")
    top = [n for n in model["class_names"] if n != "no_contact"][-1]
    face = face_class_share(top, interval, model.get("priors"), model["class_names"], edges)
    return None if face is None else face[1]
