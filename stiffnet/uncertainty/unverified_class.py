"""The alarm's class_unverified check: a class near an edge that no physical reading checks.

The model's β interval (conformal, ~90 %) often reaches across a class edge; its class is
then the model's best guess among neighbours, right most of the time in the training world,
and the restoring-force cross-check is what tells a right guess from a wrong one: where its
contact law fits closely (R² ≥ :data:`~stiffnet.uncertainty.alarm_verdict.RESTORING_FORCE_MIN_R2`)
the checks comparing the two readings confirm or dispute the class (``restoring_force_class``,
``class_contested``). Where it refused (no meaningful fit, no contact read) or its law fits
loosely (a damped contact, a sensor chain, a contact law the library lacks), nothing does,
and the class near the edge is the model's guess alone. On the robustness benchmark's draws
15 of the 21 wrong classes without any alarm were of this kind (damped contacts, with and
without a sensor chain, power-law and Hunt-Crossley contacts; the other 6 are Hertz contacts
both readings read alike: docs/serving.md, the alarm).

The score (:func:`unverified_class_share`) is the share (in log β) of the model's own
interval outside the class it answered, where the cross-check has no close-fitting reading;
it does not apply where it has one. It fires above
:attr:`UnverifiedClassSettings.outside_share_min` (``configs/alarm/unverified_class.yaml``),
set on draws of the robustness sets other than the benchmark's own (the alarm's 4 % target
on right answers of the sets inside the training priors). pydantic and the standard
library only: the predictor imports it.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from stiffnet.uncertainty.alarm_verdict import (
    class_ranges,
    restoring_force_class_share,
    share_outside,
    with_rule_check,
)

#: The check's name in an alarm's ``fired`` list.
CLASS_UNVERIFIED = "class_unverified"
#: The shipped settings (``configs/alarm/unverified_class.yaml``), relative to the package.
SETTINGS_CONFIG = "alarm/unverified_class.yaml"


class UnverifiedClassSettings(BaseModel):
    """Settings of the ``class_unverified`` check (``configs/alarm/unverified_class.yaml``)."""

    model_config = ConfigDict(extra="forbid")

    #: Share (in log β) of the model's interval outside its class above which an answer no
    #: physical reading confirms is flagged.
    outside_share_min: float = Field(0.35, ge=0.0, lt=1.0)


@lru_cache(maxsize=1)
def unverified_class_settings() -> UnverifiedClassSettings:
    """The shipped settings: ``configs/alarm/unverified_class.yaml``, else the defaults."""
    from stiffnet.config import shipped_settings

    return shipped_settings(UnverifiedClassSettings, SETTINGS_CONFIG)


def close_reading(
    class_name: str, restoring_force: dict[str, Any], class_names: list[str], edges: Any
) -> bool:
    """Whether the restoring-force cross-check read beta from a close-fitting contact law
    (R2 >= :data:`~stiffnet.uncertainty.alarm_verdict.RESTORING_FORCE_MIN_R2`): the reading
    :func:`~stiffnet.uncertainty.alarm_verdict.restoring_force_class_share` judges. False
    where it refused, saw no contact or its law fits loosely."""
    return restoring_force_class_share(class_name, restoring_force, class_names, edges) is not None


def unverified_class_share(
    class_name: str,
    interval: list[float] | None,
    restoring_force: dict[str, Any],
    class_names: list[str],
    edges: Any,
) -> float | None:
    """Share (in log β) of the model's interval outside its class, where the restoring-force
    cross-check has no close-fitting reading (:func:`close_reading`) to confirm or dispute it.

    Where it has one, the checks that compare the two readings judge the class
    (``restoring_force``, ``restoring_force_class``, ``class_contested``) and this one does
    not apply.

    Parameters
    ----------
    class_name : str
        The class answered.
    interval : list of float, optional
        The model's β interval ``[lo, hi]``.
    restoring_force : dict
        The cross-check on the same samples: ``class``, ``beta_interval``, ``contact_r2``
        (a refusal has ``class`` and ``beta_interval`` null).
    class_names : list of str
        The model's classes, ``no_contact`` (if any) then the contact classes in β order.
    edges : list of float
        The contact classes' β edges ``[lo, e1, ..., hi]``.

    Returns
    -------
    float or None
        0 inside the class, 1 for an interval wholly outside it (the ``class_beta`` check's
        case); None with a close-fitting reading, without an interval, for ``no_contact`` or
        when the edges do not match the classes.
    """
    names, low, high = class_ranges(class_names, edges)
    if not interval or class_name not in names:
        return None
    lo, hi = (float(v) for v in interval)
    if not 0 < lo < hi:
        return None
    if close_reading(class_name, restoring_force, class_names, edges):
        return None
    i = names.index(class_name)
    return share_outside(lo, hi, low[i], high[i])


def with_unverified_class_check(
    alarm: dict[str, Any] | None,
    class_name: str,
    interval: list[float] | None,
    restoring_force: dict[str, Any],
    class_names: list[str],
    edges: Any,
) -> dict[str, Any] | None:
    """The alarm with the ``class_unverified`` check added (:func:`unverified_class_share`
    against :attr:`UnverifiedClassSettings.outside_share_min`)."""
    share = unverified_class_share(class_name, interval, restoring_force, class_names, edges)
    threshold = unverified_class_settings().outside_share_min
    return with_rule_check(alarm, CLASS_UNVERIFIED, share, threshold)
