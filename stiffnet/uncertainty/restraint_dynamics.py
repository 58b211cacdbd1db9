r"""The alarm's restraint-dynamics check: a contact force that rises and falls within one impact.

Every contact law of the training world (the linear spring of paper eqs 11-12, its
Kelvin-Voigt damping, Hertz's exponent, behind the sensor chains of the priors) is a
function of the present penetration and its rate, ``F = K d_r (delta/d_r)^p + c v``,
and acts on a stop that does not move. Within one impact the mass presses in and is
pushed out once, so the force rises to one peak and falls back: one peak per impact.

A restraint with dynamics of its own does not: where the stop is the tip of a beam (a
face of modal mass ``mu`` on its support), the contact force ``F = beta (x - e - y)``
pushes the face back (``y``), the face springs forward again, and during one contact
the force rings at the frequency of the face between the contact spring and its
support (``sqrt((beta + kappa) / mu)`` in units of the natural frequency, several times
the contact's own). The map then shows two or three humps per impact, the force
falling while the mass still presses in, down to near zero between them (chatter
within the contact). Its law is linear, so the contact-law check
(:mod:`stiffnet.uncertainty.unseen_law`) cannot see it, and the beam's tip compliance
in series with the contact makes the rig read softer than its contact: the model's
class is then a class or two too soft (docs/crosscheck.md).

The statistic (:func:`second_peak_share`): within each impact (the samples the
fitted law has in contact, one sample either side), the contact force's peaks and
their prominences (:func:`scipy.signal.find_peaks`); the second-largest prominence
over the impact's peak force, 0 for one peak. For two humps of heights ``h1 >= h2``
with a dip to ``m`` between them it is ``(h2 - m) / h1``. The median over impacts is
what the rule reads (:func:`restraint_dynamics_reasons`): one noisy impact does not
count, a restraint that rings in every impact does. The humps must be resolved: with
fewer than :attr:`RestraintDynamicsThresholds.min_samples_per_contact` samples per
contact nothing is judged.

The threshold is read from ``configs/alarm/restraint_dynamics.yaml``
(:func:`restraint_dynamics_thresholds`), set on the training world's sets
(docs/crosscheck.md). numpy/scipy only: the predictor imports it.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.signal import find_peaks

from stiffnet.uncertainty.alarm_verdict import alarm_message
from stiffnet.uncertainty.law_shape import impact_runs

#: The check's name in an alarm's ``fired`` list.
RESTRAINT_DYNAMICS = "restraint_dynamics"
#: The shipped thresholds (``configs/alarm/restraint_dynamics.yaml``), relative to the package.
THRESHOLDS_CONFIG = "alarm/restraint_dynamics.yaml"


class RestraintDynamicsThresholds(BaseModel):
    """Settings of the ``restraint_dynamics`` check (``configs/alarm/restraint_dynamics.yaml``)."""

    model_config = ConfigDict(extra="forbid")

    #: Median second-peak share (:func:`second_peak_share`) from which the check fires.
    second_peak_min: float = Field(0.08, gt=0.0, lt=1.0)
    #: Fewest impacts to judge.
    min_impacts: int = Field(4, ge=2)
    #: Fewest samples in contact per impact (median) to judge: humps need resolving.
    min_samples_per_contact: int = Field(6, ge=3)


@lru_cache(maxsize=1)
def restraint_dynamics_thresholds() -> RestraintDynamicsThresholds:
    """The shipped settings: ``configs/alarm/restraint_dynamics.yaml``, else the defaults."""
    from stiffnet.config import shipped_settings

    return shipped_settings(RestraintDynamicsThresholds, THRESHOLDS_CONFIG)


def impact_second_peak(force: np.ndarray) -> float:
    """The second-largest peak prominence of one impact's force over its peak force.

    The force is padded with zeros on both sides (the restraint gives none before the touch
    and after the release), so the main peak's prominence is its height; 0 for an impact
    whose force has one peak, and 0 for an impact without a positive force.
    """
    f = np.asarray(force, float)
    top = float(f.max(initial=0.0))
    if not top > 0:
        return 0.0
    _, props = find_peaks(np.r_[0.0, f, 0.0], prominence=0.0)
    prominences = np.sort(props["prominences"])[::-1]
    return float(prominences[1] / top) if prominences.size > 1 else 0.0


def second_peak_share(
    disp: np.ndarray,
    force: np.ndarray,
    onset: float,
    thresholds: RestraintDynamicsThresholds | None = None,
) -> dict[str, float] | None:
    """How far the contact force rises again within one impact, the median over impacts.

    Parameters
    ----------
    disp, force : numpy.ndarray
        The restoring-force map's displacement and contact force (consecutive samples).
    onset : float
        The fitted contact law's ``e``: an impact is a run of samples with ``disp > onset``,
        read with one sample either side.
    thresholds : RestraintDynamicsThresholds, optional
        ``min_impacts`` and ``min_samples_per_contact``; default the shipped ones.

    Returns
    -------
    dict or None
        ``second_peak`` (the median over impacts of :func:`impact_second_peak`),
        ``second_peak_impacts`` (the share of impacts whose own value reaches the
        threshold ``second_peak_min``) and ``n_impacts``; None with fewer impacts than
        ``min_impacts`` or a median contact shorter than ``min_samples_per_contact``.
    """
    t = thresholds or restraint_dynamics_thresholds()
    d = np.asarray(disp, float) - onset
    f = np.asarray(force, float)
    runs = impact_runs(d)
    if len(runs) < t.min_impacts:
        return None
    if np.median([r.size for r in runs]) < t.min_samples_per_contact:
        return None
    shares = np.array([impact_second_peak(f[max(r[0] - 1, 0) : r[-1] + 2]) for r in runs])
    return {
        "second_peak": float(np.median(shares)),
        "second_peak_impacts": float(np.mean(shares >= t.second_peak_min)),
        "n_impacts": float(len(runs)),
    }


def restraint_dynamics_reasons(
    reading: dict[str, float] | None, thresholds: RestraintDynamicsThresholds | None = None
) -> list[str]:
    """Rule: the median second-peak share (:func:`second_peak_share`) reaches
    :attr:`RestraintDynamicsThresholds.second_peak_min`: the restraint rings within its
    contacts, which no law of the training world does. Empty: not fired (or not judged)."""
    t = thresholds or restraint_dynamics_thresholds()
    if not reading or reading.get("second_peak") is None:
        return []
    share = reading["second_peak"]
    if share < t.second_peak_min:
        return []
    return [
        f"the contact force rises and falls more than once within each impact (the second "
        f"peak rises {share:.0%} of the first above the dip before it, in "
        f"{reading.get('second_peak_impacts', 0.0):.0%} of the impacts): the restraint "
        "rings during the contact, like the tip of a beam or a stop on a flexible mount, and "
        "the model reads the contact and the restraint's compliance as one softer stiffness"
    ]


def with_restraint_dynamics_check(
    alarm: dict[str, Any] | None,
    restoring_force: dict[str, Any],
    seen: frozenset[str] = frozenset(),
) -> dict[str, Any] | None:
    """The alarm with the ``restraint_dynamics`` check added, where the cross-check could
    read the impacts (``restoring_force["impact_peaks"]``, :func:`second_peak_share`).

    Its score is the median second-peak share and its threshold
    :attr:`RestraintDynamicsThresholds.second_peak_min`; the reasons go to
    ``alarm["restraint_dynamics"]``. `seen`: the kinds of law the model was trained on
    (:func:`stiffnet.uncertainty.unseen_law.trained_law_kinds`); a model trained with a
    face of its own (:data:`RESTRAINT_DYNAMICS` among them) is not judged. A model without
    an alarm gets one made of this check.
    """
    reading = restoring_force.get("impact_peaks")
    if RESTRAINT_DYNAMICS in seen or not reading or reading.get("second_peak") is None:
        return alarm
    t = restraint_dynamics_thresholds()
    reasons = restraint_dynamics_reasons(reading, t)
    if alarm is None:
        alarm = {"flag": False, "fired": [], "scores": {}, "thresholds": {}}
    alarm = {**alarm, "scores": dict(alarm["scores"]), "thresholds": dict(alarm["thresholds"])}
    alarm["scores"][RESTRAINT_DYNAMICS] = float(reading["second_peak"])
    alarm["thresholds"][RESTRAINT_DYNAMICS] = t.second_peak_min
    if reasons:
        alarm["fired"] = [*alarm["fired"], RESTRAINT_DYNAMICS]
        alarm["flag"] = True
        alarm[RESTRAINT_DYNAMICS] = reasons
    alarm["message"] = alarm_message(alarm["fired"])
    return alarm
