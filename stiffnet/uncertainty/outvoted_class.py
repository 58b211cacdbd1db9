"""The alarm's class_outvoted check: both physical readings lean to one side of the model's class.

A recording carries two physical readings of beta beside the model's: the geometric one (the
paper's inclinations of the delay embedding, calibrated to a class) and the restoring-force
cross-check (a contact law fitted to the reconstructed force against penetration). Each is
independent of the model and of the other: the first reads angles of the orbit, the second a
force map. Where the restoring-force law fits closely, the checks that compare its interval
with the model's judge the class (``restoring_force_class``, ``class_contested``); where it
fits loosely (a damped contact behind a sensor chain: R2 0.74-0.93 on the robustness
benchmark's ``damping_and_sensor`` draws) its class alone is a coin against the model's.

Two readings that name classes on the same side of the model's class are a vote,
though, where the model's own interval does not place beta firmly in its class. The check
applies where both name a contact class on one side (both softer, or both harder) of the
class answered; its score is then the share (in log beta) of the model's own interval outside
that class (``class_unverified``'s score, which fires alone only above 0.35): an interval
wholly inside the class has placed beta there on its own and the check stays quiet. On the
draws the benchmark does not score it fired on 7 answers no other check flagged, 4 of them
wrong (docs/measurement_loop.md, "Two physical readings against the model's class").
It fires above :attr:`OutvotedClassSettings.outside_share_min`
(``configs/alarm/outvoted_class.yaml``). pydantic and the standard library only: the
predictor imports it.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from stiffnet.uncertainty.alarm_verdict import class_ranges, share_outside, with_rule_check

#: The check's name in an alarm's ``fired`` list.
CLASS_OUTVOTED = "class_outvoted"
#: The shipped settings (``configs/alarm/outvoted_class.yaml``), relative to the package.
SETTINGS_CONFIG = "alarm/outvoted_class.yaml"


class OutvotedClassSettings(BaseModel):
    """Settings of the ``class_outvoted`` check (``configs/alarm/outvoted_class.yaml``)."""

    model_config = ConfigDict(extra="forbid")

    #: Share (in log β) of the model's interval outside its class above which an answer both
    #: physical readings place on one side of that class is flagged.
    outside_share_min: float = Field(0.05, ge=0.0, lt=1.0)


@lru_cache(maxsize=1)
def outvoted_class_settings() -> OutvotedClassSettings:
    """The shipped settings: ``configs/alarm/outvoted_class.yaml``, else the defaults."""
    from stiffnet.config import shipped_settings

    return shipped_settings(OutvotedClassSettings, SETTINGS_CONFIG)


def readings_side(class_name: str, readings: list[str | None], names: list[str]) -> int:
    """The side of `class_name` on which every reading names a contact class: -1 (all
    softer), +1 (all harder), 0 (a reading missing, outside `names`, in the class itself, or
    the readings split)."""
    if class_name not in names or not readings:
        return 0
    i = names.index(class_name)
    sides = {(names.index(r) > i) - (names.index(r) < i) if r in names else 0 for r in readings}
    return sides.pop() if len(sides) == 1 else 0


def outvoted_class_share(
    class_name: str,
    interval: list[float] | None,
    geometric_class: str | None,
    restoring_force: dict[str, Any] | None,
    class_names: list[str],
    edges: Any,
) -> float | None:
    """Share (in log β) of the model's interval outside its class, where both physical
    readings (geometric, restoring force) name a contact class on one side of it.

    Parameters
    ----------
    class_name : str
        The class answered.
    interval : list of float, optional
        The model's β interval ``[lo, hi]``.
    geometric_class : str, optional
        The geometric cross-check's class (``no_contact`` or None: no reading).
    restoring_force : dict, optional
        The restoring-force cross-check on the same samples; its ``class`` is the reading
        (null where it refused).
    class_names : list of str
        The model's classes, ``no_contact`` (if any) then the contact classes in β order.
    edges : list of float
        The contact classes' β edges ``[lo, e1, ..., hi]``.

    Returns
    -------
    float or None
        0 inside the class, 1 for an interval wholly outside it; None where the readings
        do not both name a contact class on one side of the class answered, without an
        interval, for ``no_contact`` or when the edges do not match the classes.
    """
    names, low, high = class_ranges(class_names, edges)
    if not interval or class_name not in names:
        return None
    lo, hi = (float(v) for v in interval)
    if not 0 < lo < hi:
        return None
    physical = [geometric_class, (restoring_force or {}).get("class")]
    side = readings_side(class_name, physical, names)
    if side == 0:
        return None
    i = names.index(class_name)
    return share_outside(lo, hi, low[i], high[i])


def with_outvoted_class_check(
    alarm: dict[str, Any] | None,
    class_name: str,
    interval: list[float] | None,
    geometric_class: str | None,
    restoring_force: dict[str, Any] | None,
    class_names: list[str],
    edges: Any,
) -> dict[str, Any] | None:
    """The alarm with the ``class_outvoted`` check added (:func:`outvoted_class_share`
    against :attr:`OutvotedClassSettings.outside_share_min`)."""
    share = outvoted_class_share(
        class_name, interval, geometric_class, restoring_force, class_names, edges
    )
    threshold = outvoted_class_settings().outside_share_min
    return with_rule_check(alarm, CLASS_OUTVOTED, share, threshold)
