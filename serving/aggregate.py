"""The predictor's aggregation step: per-window model outputs -> the recording's answer.

Class probabilities: the mean of the windows' probabilities (robust to one odd
window, unlike a product of probabilities); class: its arg-max. Beta: ``exp``
of the mean log beta over the windows whose own class has contact
(:func:`stiffnet.uncertainty.aggregate_windows`, the same function that
calibrated the model on whole training trajectories); its interval is
:func:`stiffnet.uncertainty.beta_interval`. Segments aggregate consecutive
windows the same way. The geometric cross-check aggregates its windows' inclinations:
contact if at least half of them have contact, then the mean inclinations of
the windows on the recording's orbit (period-1 or not, as most of them) through
the calibration's map for that orbit give beta and class.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from stiffnet.geometry.orbit import is_period1
from stiffnet.uncertainty import RecordingEstimate, aggregate_windows
from stiffnet.uncertainty.class_decision import ClassDecision


def named(class_names: list[str], p: np.ndarray) -> dict[str, float]:
    """Probabilities by class name."""
    return {n: float(v) for n, v in zip(class_names, p, strict=True)}


def segments(
    out: dict[str, np.ndarray],
    starts: np.ndarray,
    window: int,
    n_samples: int,
    fs: float,
    per_segment: int,
    class_names: list[str],
    no_contact: int | None,
    decide: Callable[[RecordingEstimate], ClassDecision] | None = None,
) -> list[dict[str, Any]]:
    """The record in tiles of `per_segment` window lengths, each aggregated like the recording.

    A window belongs to the tile holding its centre (the windows slide, so each
    tile gets the windows centred in it and none is counted twice); a tile
    without a window is left out; the last tile ends with the record. `decide` gives a
    tile's class as the recording's (:meth:`serving.predictor.Predictor.decide_class`);
    without it the class head's arg-max.
    """
    span = per_segment * window
    tile = (np.asarray(starts) + window // 2) // span
    found = []
    for k in np.unique(tile):
        run = {name: v[tile == k] for name, v in out.items()}
        seg = aggregate_windows(
            run["probabilities"], run["log_beta"], run.get("log_beta_scale"), no_contact
        )
        label, by = seg.label, "class_head"
        if decide is not None:
            decision = decide(seg)
            label, by = decision.label, decision.decided_by
        found.append(
            {
                "index": len(found),
                "start_s": float(k * span / fs),
                "end_s": float(min(n_samples, (k + 1) * span) / fs),
                "n_windows": int((tile == k).sum()),
                "class": class_names[label],
                "class_decided_by": by,
                "probabilities": named(class_names, seg.probabilities),
                "beta": math.exp(seg.log_beta) if seg.log_beta is not None else None,
            }
        )
    return found


def geometric_verdict(results: list, calibration: Any) -> dict[str, Any]:
    """Aggregate the per-window geometric results (contact in >= half the windows)."""
    contact = [r for r in results if r is not None and r.contact_detected]
    n = len(results)
    out: dict[str, Any] = {
        "class": "no_contact",
        "beta": None,
        "inclination_before_deg": None,
        "inclination_after_deg": None,
        "contact_detected": False,
        "n_windows": n,
        "n_windows_with_contact": len(contact),
        "polarity": 0,
    }
    if not contact or 2 * len(contact) < n:
        return out
    # the 'before' angle reads the orbit: average windows of one kind, use its map
    one = [is_period1(r.impact_pattern) for r in contact]
    period1 = 2 * sum(one) >= len(contact)
    same = [r for r, o in zip(contact, one, strict=True) if o == period1]
    before = float(np.mean([r.inclination_before_deg for r in same]))
    after = float(np.mean([r.inclination_after_deg for r in same]))
    beta, cls = calibration.for_orbit((1, 1) if period1 else None).predict((before, after))
    pol = int(np.sign(sum(r.polarity for r in contact))) or contact[0].polarity
    out.update(
        {
            "class": str(cls),
            "inclination_before_deg": before,
            "inclination_after_deg": after,
            "contact_detected": True,
            "polarity": pol,
            "beta": float(beta) if np.isfinite(beta) else None,
        }
    )
    return out
