"""Which head gives a recording's class: the class head, or the beta head near a class edge.

A model reads two things from the same windows: class probabilities (the class head) and
log beta (the beta head); the classes are beta bins (the model's ``class_edges``). Where
the two disagree on neighbouring classes, beta lies near their shared edge and the class
head's top probability is not decisive, the two heads weigh the same evidence differently.
Which of them is right there is a property of the model, measured on held-out recordings
(``benchmarks/bench_class_decision.py``): the rule is set per model family in
``configs/class_decision.yaml`` and is off for a family not listed there.

The class probabilities are reported as the class head gave them; the decision only names
the class, and says which head gave it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from stiffnet.uncertainty.aggregate import RecordingEstimate

#: The shipped per-family rule (under ``configs/``).
CLASS_DECISION_CONFIG = "class_decision.yaml"
#: ``decided_by`` values.
CLASS_HEAD, BETA_HEAD = "class_head", "beta_head"


class FamilyRule(BaseModel):
    """When a family's beta head names the class.

    Attributes
    ----------
    max_head_probability : float
        The class head decides when its top probability reaches this (it is decisive).
    """

    model_config = ConfigDict(extra="forbid")

    max_head_probability: float = Field(gt=0.0, le=1.0)


class ClassDecisionConfig(BaseModel):
    """The rule per model family (``cnn``, ``gbm``); a family not listed keeps the class head."""

    model_config = ConfigDict(extra="forbid")

    families: dict[str, FamilyRule] = Field(default_factory=dict)


@lru_cache(maxsize=1)
def class_decision_config() -> ClassDecisionConfig:
    """The shipped rule: ``configs/class_decision.yaml``, else none (the class head decides)."""
    from stiffnet.config import shipped_settings

    return shipped_settings(ClassDecisionConfig, CLASS_DECISION_CONFIG)


def family_rule(kind: str) -> FamilyRule | None:
    """The shipped rule of a model family (None: the class head decides)."""
    return class_decision_config().families.get(kind)


@dataclass(frozen=True)
class ClassDecision:
    """A recording's class and where it came from.

    Attributes
    ----------
    label : int
        The reported class (index into the model's classes).
    class_head : int
        Arg-max of the class probabilities.
    beta_class : int or None
        The class whose beta range holds the beta head's estimate (None: no beta, or the
        edges do not match the classes).
    decided_by : str
        :data:`CLASS_HEAD` or :data:`BETA_HEAD`.
    """

    label: int
    class_head: int
    beta_class: int | None
    decided_by: str


def beta_class_index(log_beta: float | None, class_names: list[str], edges: Any) -> int | None:
    """Index (into `class_names`) of the contact class whose beta range holds ``exp(log_beta)``.

    The contact classes are the names other than ``no_contact``, in beta order, with edges
    ``[lo, e1, ..., hi]`` (one more than the classes); the outer classes are open-ended, as
    in the alarm's class checks. None without a beta or when the edges do not match.
    """
    if log_beta is None or not math.isfinite(log_beta) or not isinstance(edges, list | tuple):
        return None
    contact = [i for i, c in enumerate(class_names) if c != "no_contact"]
    if len(edges) != len(contact) + 1 or not contact:
        return None
    for i, edge in zip(contact[:-1], edges[1:-1], strict=True):
        if log_beta < math.log(float(edge)):  # in logs: exp(log(35)) may fall short of 35
            return i
    return contact[-1]


def decide_class(
    estimate: RecordingEstimate,
    class_names: list[str],
    edges: Any,
    rule: FamilyRule | None,
) -> ClassDecision:
    """The class of a recording from its two heads.

    The beta head decides when all hold: a rule is given; the class head names a contact
    class; the beta estimate lies in a neighbouring contact class (one edge apart: beta is
    near that edge, on the other side); the class head's top probability is below
    ``rule.max_head_probability``. Otherwise the class head decides (its arg-max, as
    :func:`~stiffnet.uncertainty.aggregate_windows` gives it).

    Parameters
    ----------
    estimate : RecordingEstimate
        The recording's aggregated windows.
    class_names : list of str
        The model's classes, ``no_contact`` (if any) then the contact classes in beta order.
    edges : list of float
        The contact classes' beta edges (the model's ``class_edges``).
    rule : FamilyRule or None
        The model family's rule (:func:`family_rule`); None keeps the class head.
    """
    head = int(estimate.label)
    beta = beta_class_index(estimate.log_beta, class_names, edges)
    keep = ClassDecision(head, head, beta, CLASS_HEAD)
    if rule is None or beta is None or class_names[head] == "no_contact":
        return keep
    if abs(beta - head) != 1 or class_names[beta] == "no_contact":
        return keep
    if float(estimate.probabilities[head]) >= rule.max_head_probability:
        return keep
    return ClassDecision(beta, head, beta, BETA_HEAD)
