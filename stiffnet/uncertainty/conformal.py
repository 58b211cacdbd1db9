"""Split-conformal intervals with one normalised score per trajectory.

Windows cut from one trajectory share its parameters, so their errors are
correlated: a quantile of per-window residuals is calibrated on far fewer
independent draws than it counts, and it is applied to a mean over windows
that it was not calibrated on. Here each calibration trajectory gives one
score, the error of its aggregated estimate (:func:`aggregate_windows`, the
predictor's aggregation) divided by that estimate's scale (normalised, or
locally weighted, conformal prediction: Papadopoulos et al. 2008; Lei et al.
2018, sec. 5.2). The interval of a recording is ``log_beta +- q * scale``:
wide where the model says it is unsure or its windows disagree, narrow
elsewhere, with the split-conformal guarantee of marginal coverage over
recordings exchangeable with the calibration trajectories.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from stiffnet.uncertainty.aggregate import RecordingEstimate


def conformal_quantile(scores: np.ndarray, coverage: float) -> float:
    """Split-conformal quantile: the ``ceil((n + 1) coverage)``-th smallest score.

    Parameters
    ----------
    scores : numpy.ndarray
        Non-conformity scores of the calibration units (absolute values are used).
    coverage : float
        Target coverage in (0, 1).

    Returns
    -------
    float
        The quantile (``inf`` if there are too few scores for the coverage).
    """
    if not 0.0 < coverage < 1.0:
        raise ValueError(f"coverage must be in (0, 1), got {coverage}")
    r = np.sort(np.abs(np.asarray(scores, dtype=np.float64)))
    n = r.size
    k = math.ceil((n + 1) * coverage)
    return float(r[k - 1]) if 0 < k <= n else float("inf")


def normalized_scores(estimate: np.ndarray, scale: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Scores ``|truth - estimate| / scale`` (log-beta units cancel)."""
    estimate, scale, truth = (np.asarray(a, dtype=np.float64) for a in (estimate, scale, truth))
    if np.any(~(scale > 0)):
        raise ValueError("scales must be > 0")
    return np.abs(truth - estimate) / scale


def beta_interval(
    est: RecordingEstimate, metadata: dict[str, Any], conformal_quantile: float | None
) -> list[float] | None:
    """Applying the interval: ``exp(log_beta +- q scale)`` of one recording.

    ``q`` is the model's normalised quantile calibrated with one score per
    trajectory (metadata ``conformal_quantile_recording``, :func:`conformal_quantile`
    of :func:`normalized_scores`); a model without it falls back to its per-window
    half-width ``conformal_quantile`` (``exp(log_beta +- q)``). None without a
    contact class or a quantile.
    """
    if est.log_beta is None:
        return None
    q_rec = metadata.get("conformal_quantile_recording")
    if isinstance(q_rec, int | float) and math.isfinite(q_rec) and est.scale is not None:
        half = float(q_rec) * est.scale
    elif conformal_quantile:
        half = conformal_quantile
    else:
        return None
    return [math.exp(est.log_beta - half), math.exp(est.log_beta + half)]


def interval_behind_alarm(
    interval: list[float] | None,
    restoring_force_interval: list[float] | None,
    contact_r2: float | None,
    min_r2: float,
) -> list[float] | None:
    """The model's interval joined with the restoring-force one, for a recording the alarm flags.

    The conformal guarantee holds for recordings exchangeable with the calibration
    trajectories; a flagged one is not (a sensor chain or a contact the training world
    lacks), and there the model's interval covered 0.83-0.86 of lab-chain recordings
    (bench_crosscheck's rig_chains / sensor_chains). The restoring-force estimate reads
    beta from the contact law itself, so where its law fits closely (``contact_r2 >=
    min_r2``) the span of both intervals keeps the answer honest: it is never narrower
    than the model's. The caller applies it only when the alarm fired. None without
    the model's interval; the model's own when the cross-check has none or fits loosely.
    """
    if not interval:
        return interval
    if not restoring_force_interval or contact_r2 is None or not contact_r2 >= min_r2:
        return list(interval)
    lo, hi = (float(v) for v in restoring_force_interval)
    if not 0 < lo <= hi:
        return list(interval)
    return [min(float(interval[0]), lo), max(float(interval[1]), hi)]
