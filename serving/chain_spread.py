"""The learned model behind a fitted sensor chain: its interval spans the chains the fit allows.

The predictor divides the identified chain out of the record before the model reads it
(:mod:`serving.chain_undo`). A data sheet's chain is known; a chain fitted from the impacts
(the restoring-force check's, or a campaign's pooled one) is not: its low-pass corner is
read high by the pulse model (14-16 % on the independent rig's campaigns, outside the fit's
own interval), and a corner undone too high leaves part of the low-pass in the record, which
the model reads as a softer contact. The conformal interval was calibrated on records whose
chain was either absent or in the training priors, so it does not know the chain it undid
was a guess.

:func:`plausible_chains` names the other chains the record may have passed through (as
recorded, the low-pass corner lower, the resonance at the ends of its fitted interval, the
high-pass left in: ``configs/chain_spread.yaml``); the predictor reads the model through
each, and the answer's interval spans theirs (:func:`spread_interval`). Where the readings
land in different classes the class is a guess at the chain, and the ``chain_class`` alarm
says so (:func:`chain_class_share`). A data sheet's chain, or no chain, is read once: the interval
is the model's own.

**When the record as recorded is no alternative.** The reading as recorded stands for a
fitted chain that is not the record's: a resonance or low-pass the pulse model took to
reshape a contact it cannot draw (a damped contact read through a 93-118 Hz "mount" over an
18-22 Hz contact). A resonance can reshape a pulse only within the pulse's band; one far
above the contact (:data:`~serving.campaign_chain.RESONANCE_NEAR_CONTACT` times it, where,
as the campaign chain notes, its inverse barely touches the pulse) and lightly damped
(:data:`~stiffnet.restoring_force.sensor.RINGING_MAX_DAMPING`, a mount's) was kept by the
fit for the ring it leaves after every impact, which no contact draws. Where, besides, the
fit's own contact is the one the model reads through the chain (inside the model's
interval: the pulse was not bent to fit the resonance), the record passed through that
resonance (:func:`resonance_rings_clear`), and the record as recorded is not read: the
model would read a mount it was not trained behind (on the independent rig's 237 Hz mount
it read β 41-100 for 35-83, a class too hard on 5 of 24), and ``chain_class`` would fire
on answers the chain leaves in no doubt. A resonance near the contact, one undone with a
low-pass, or a fit whose contact the model does not read keeps the reading; so does every
caller that passes no model reading (the stiffness log chooses its chains before it reads).

The predictor and the stiffness log import it: pydantic, and the two constants above from
their modules (numpy and scipy; never torch, scikit-learn or mlflow).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field

from serving.campaign_chain import RESONANCE_NEAR_CONTACT
from stiffnet.restoring_force.sensor import RINGING_MAX_DAMPING

#: The shipped settings (under ``configs/``).
CHAIN_SPREAD_CONFIG = "chain_spread.yaml"
#: Where a chain came from when the predictor spreads over it: fitted on this record, or a
#: campaign's pooled fits (:mod:`serving.campaign_chain`).
FITTED_SOURCES = ("fitted", "campaign")


class ChainSpreadConfig(BaseModel):
    """Which other chains a fitted one stands for.

    Attributes
    ----------
    enabled : bool
        Off: the model reads the fitted chain alone (the interval as calibrated).
    as_recorded : bool
        Also read the record as recorded (nothing undone), except behind a resonance alone
        that rings clear of the contact the model reads (:func:`resonance_rings_clear`).
    lowpass_factors : list of float
        Also read it with the fitted low-pass corner times each factor undone.
    resonance_interval : bool
        Also read it with the resonance at each end of its fitted interval (a fit without
        an interval: none).
    highpass_kept : bool
        Also read it with the fitted high-pass corner left in (the other stages undone):
        the corner is a fit too, and the model reads a high-pass as stiffness.
    """

    model_config = ConfigDict(extra="forbid")

    enabled: bool = True
    as_recorded: bool = True
    lowpass_factors: list[Annotated[float, Field(ge=0.2, le=5.0)]] = Field(default_factory=list)
    resonance_interval: bool = False
    highpass_kept: bool = False


@lru_cache(maxsize=1)
def chain_spread_config() -> ChainSpreadConfig:
    """The shipped settings: ``configs/chain_spread.yaml``, else the defaults."""
    from stiffnet.config import shipped_settings

    return shipped_settings(ChainSpreadConfig, CHAIN_SPREAD_CONFIG)


def plausible_chains(
    sensor: dict | None,
    undone: dict | None,
    config: ChainSpreadConfig,
    contact_read: list[float] | None = None,
) -> dict[str, dict | None]:
    """The other chains a fitted one stands for, by name (None: the record as recorded).

    Parameters
    ----------
    sensor : dict or None
        The chain the model read undone (the restoring-force check's ``sensor``).
    undone : dict or None
        What :func:`serving.chain_undo.model_record` divided out, with its ``source``
        (``fitted``, ``campaign`` or ``data sheet``).
    config : ChainSpreadConfig
    contact_read : list of float, optional
        The contact's frequency (Hz) the model reads through the chain: the low end of its
        interval, its β, the high end (:func:`contact_frequencies`). Without it the record
        as recorded is always read.

    Returns
    -------
    dict
        Empty where nothing fitted was undone (no chain, a data sheet, or switched off).
    """
    if not (config.enabled and sensor and undone) or undone.get("source") not in FITTED_SOURCES:
        return {}
    out: dict[str, dict | None] = {}
    if config.as_recorded and not resonance_rings_clear(sensor, undone, contact_read):
        out["as recorded"] = None
    corner = undone.get("lowpass_hz")
    for f in config.lowpass_factors if corner else ():
        out[f"low-pass {f * corner:.0f} Hz"] = {**sensor, "lowpass_hz": f * corner}
    ends = (sensor.get("intervals") or {}).get("resonance_hz")
    if config.resonance_interval and undone.get("resonance_hz") and ends:
        for end in ends:
            out[f"resonance {end:.0f} Hz"] = {**sensor, "resonance_hz": float(end)}
    highpass = undone.get("highpass_hz")
    if config.highpass_kept and highpass:
        out[f"high-pass {highpass:.2g} Hz kept"] = {**sensor, "highpass_hz": 0.0}
    return out


def contact_frequencies(
    beta: float | None, interval: list[float] | None, fn_hz: float
) -> list[float] | None:
    """The contact's frequency ``f_n sqrt(1 + beta)`` (Hz) at the low end of `interval`, at
    `beta` and at the high end; None without both."""
    if beta is None or not interval:
        return None
    return [fn_hz * math.sqrt(1.0 + max(float(b), 0.0)) for b in (interval[0], beta, interval[1])]


def resonance_rings_clear(
    sensor: dict, undone: dict, contact_read: list[float] | None = None
) -> bool:
    """Whether the chain undone is a resonance alone that the fit kept for its ring: lightly
    damped (below :data:`~stiffnet.restoring_force.sensor.RINGING_MAX_DAMPING`); the fit's
    contact frequency inside the one the model reads through the chain (`contact_read`'s
    ends); and, over its whole fitted interval, at least
    :data:`~serving.campaign_chain.RESONANCE_NEAR_CONTACT` times the fastest of the fit's
    contact (the top of its ``contact_hz`` interval) and the model's (at its β).

    Parameters
    ----------
    sensor : dict
        The fitted chain (the restoring-force check's ``sensor``: ``resonance_damping``,
        ``contact_hz``, ``intervals``).
    undone : dict
        The stages divided out (:func:`serving.chain_undo.model_record`).
    contact_read : list of float, optional
        The model's contact frequency through the chain, ``[low, at beta, high]`` (Hz,
        :func:`contact_frequencies`).

    Returns
    -------
    bool
        False without the model's reading, where a low-pass was undone too (a low-pass
        reshapes the pulse wherever it lies), where the fit gives no contact frequency or
        one the model does not read, or where the resonance lies near the contact: there
        the record as recorded stays a reading.
    """
    resonance = undone.get("resonance_hz")
    if not (resonance and contact_read) or undone.get("lowpass_hz"):
        return False
    damping = sensor.get("resonance_damping")
    fitted = sensor.get("contact_hz")
    if damping is None or not fitted or not 0 < float(damping) < RINGING_MAX_DAMPING:
        return False
    low, at_beta, high = (float(v) for v in contact_read)
    if not low <= float(fitted) <= high:
        return False  # the fit's pulse is not the model's contact: it may have been bent
    intervals = sensor.get("intervals") or {}
    fastest = max(float((intervals.get("contact_hz") or [fitted])[-1]), at_beta)
    lowest = min([float(resonance), *(float(v) for v in intervals.get("resonance_hz") or ())])
    return lowest >= RESONANCE_NEAR_CONTACT * fastest


def spread_interval(
    interval: list[float] | None, readings: Sequence[dict[str, Any]]
) -> list[float] | None:
    """The span of the model's interval and the readings' (``beta_interval`` each; one without
    any adds nothing). None without the model's own."""
    if not interval:
        return interval
    lo, hi = float(interval[0]), float(interval[1])
    for r in readings:
        other = r.get("beta_interval")
        if other:
            lo, hi = min(lo, float(other[0])), max(hi, float(other[1]))
    return [lo, hi]


def chain_class_share(class_name: str, readings: Sequence[dict[str, Any]]) -> float | None:
    """Share of the readings through the other plausible chains that land in another class
    than `class_name` (None without any: the check does not apply). The ``chain_class``
    alarm fires above 0."""
    if not readings:
        return None
    return sum(r.get("class") != class_name for r in readings) / len(readings)
