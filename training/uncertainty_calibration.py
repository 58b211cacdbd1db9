"""Recording-level calibration of a trained model: its interval and its alarm.

Everything is calibrated on whole *trajectories* of the calibration split,
aggregated exactly as the predictor aggregates a recording's windows
(:func:`stiffnet.uncertainty.aggregate_windows`):

* the interval: one normalised conformal score per trajectory
  (:mod:`stiffnet.uncertainty.conformal`);
* the alarm: each check's score per trajectory, thresholds at a common
  percentile so that at most ``target`` of the trajectories are flagged
  (:func:`stiffnet.uncertainty.alarm.calibrate_thresholds`).

:func:`trajectory_metrics` scores the same quantities on the test trajectories:
accuracy, beta MAPE, interval coverage, alarm rate overall and on the
trajectories whose class is wrong.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from stiffnet.uncertainty import aggregate_windows, conformal_quantile, normalized_scores
from stiffnet.uncertainty.alarm import (
    AlarmReference,
    calibrate_thresholds,
    fit_embedding_reference,
    recording_checks,
)

#: Training windows kept as the embedding reference of the alarm (size of the shipped file).
MAX_REFERENCE_WINDOWS = 4000


@dataclass
class TrajectoryTable:
    """Per-trajectory aggregates of window outputs (one row per trajectory)."""

    trajectory: np.ndarray
    label: np.ndarray  # true class
    beta: np.ndarray  # true beta
    pred: np.ndarray  # aggregated class
    log_beta: np.ndarray  # aggregated log beta (NaN: no contact predicted)
    scale: np.ndarray  # its error scale (NaN: no contact predicted)
    checks: dict[str, np.ndarray]


def trajectory_table(
    traj: np.ndarray,
    label: np.ndarray,
    beta: np.ndarray,
    outputs: dict[str, np.ndarray],
    alarm: AlarmReference | None = None,
    no_contact: int = 0,
    classes: np.ndarray | None = None,
) -> TrajectoryTable:
    """Aggregate window outputs (``probabilities``, ``log_beta``, optional
    ``log_beta_scale`` and ``embedding``) per trajectory, as the predictor does.

    The true label of a trajectory is its windows' majority label. ``classes`` is the
    class index of each ``probabilities`` column (default: column k is class k); a model
    trained where every window has contact (a GBM at a campaign's operating points) has no
    ``no_contact`` column, and its first column is then a contact class, as the predictor
    reads it from the model's ``class_names``.
    """
    cols = np.arange(outputs["probabilities"].shape[1]) if classes is None else np.asarray(classes)
    hit = np.flatnonzero(cols == no_contact)
    nc_column = int(hit[0]) if hit.size else None
    ids, inverse = np.unique(traj, return_inverse=True)
    emb_scores = None
    if alarm is not None and alarm.embeddings is not None and "embedding" in outputs:
        emb_scores = alarm.embedding_scores(outputs["embedding"])
    edges = (alarm.info.get("class_edges") if alarm is not None else None) or None
    rows: dict[str, list[Any]] = {k: [] for k in ("label", "beta", "pred", "lb", "scale")}
    checks: dict[str, list[float]] = {}
    for j in range(len(ids)):
        w = np.flatnonzero(inverse == j)
        est = aggregate_windows(
            outputs["probabilities"][w],
            outputs["log_beta"][w],
            outputs["log_beta_scale"][w] if "log_beta_scale" in outputs else None,
            nc_column,
        )
        rows["label"].append(int(np.bincount(label[w]).argmax()))
        rows["beta"].append(float(beta[w][0]))
        rows["pred"].append(int(cols[est.label]))
        rows["lb"].append(np.nan if est.log_beta is None else est.log_beta)
        rows["scale"].append(np.nan if est.scale is None else est.scale)
        c = recording_checks(est, None if emb_scores is None else emb_scores[w], None, edges)
        for k, v in c.items():
            checks.setdefault(k, []).append(np.nan if v is None else float(v))
    return TrajectoryTable(
        trajectory=ids,
        label=np.array(rows["label"]),
        beta=np.array(rows["beta"]),
        pred=np.array(rows["pred"]),
        log_beta=np.array(rows["lb"]),
        scale=np.array(rows["scale"]),
        checks={k: np.array(v) for k, v in checks.items() if np.isfinite(v).any()},
    )


def recording_quantile(table: TrajectoryTable, coverage: float, no_contact: int = 0) -> float:
    """Normalised conformal quantile from the contact trajectories of `table`."""
    ok = (table.label != no_contact) & np.isfinite(table.log_beta)
    scores = normalized_scores(table.log_beta[ok], table.scale[ok], np.log(table.beta[ok]))
    return conformal_quantile(scores, coverage)


def fit_alarm(
    train_embeddings: np.ndarray | None,
    cal_traj: np.ndarray,
    cal_label: np.ndarray,
    cal_beta: np.ndarray,
    cal_outputs: dict[str, np.ndarray],
    target: float,
    seed: int,
    info: dict[str, Any],
    checks: list[str] | None = None,
    classes: np.ndarray | None = None,
) -> tuple[AlarmReference, float]:
    """Reference embeddings from training windows, thresholds from calibration trajectories.

    ``checks`` limits the alarm to those checks (default: every check the model's
    outputs allow); ``classes`` as in :func:`trajectory_table`. Returns the reference
    and the fraction of calibration trajectories it flags.
    """
    ref = AlarmReference(thresholds={}, info=dict(info))
    if train_embeddings is not None and len(train_embeddings):
        emb, center, scale = fit_embedding_reference(
            train_embeddings, MAX_REFERENCE_WINDOWS, np.random.default_rng(seed)
        )
        ref.embeddings, ref.center, ref.scale = emb, center, scale
    table = trajectory_table(cal_traj, cal_label, cal_beta, cal_outputs, ref, classes=classes)
    scores = {k: v for k, v in table.checks.items() if checks is None or k in checks}
    ref.thresholds, rate = calibrate_thresholds(scores, target)
    ref.info.update({"target_false_alarm": target, "calibration_false_alarm": rate,
                     "calibration_trajectories": int(len(table.trajectory))})  # fmt: skip
    return ref, rate


def trajectory_metrics(
    table: TrajectoryTable,
    q: float,
    alarm: AlarmReference | None = None,
    no_contact: int = 0,
) -> dict[str, float]:
    """Recording-level accuracy, beta MAPE, interval coverage and alarm rates."""
    m: dict[str, float] = {"n": float(len(table.label))}
    m["accuracy"] = float(np.mean(table.pred == table.label)) if len(table.label) else np.nan
    ok = (table.label != no_contact) & np.isfinite(table.log_beta)
    if ok.any():
        lb, y, s = table.log_beta[ok], np.log(table.beta[ok]), table.scale[ok]
        m["beta_mape"] = float(np.mean(np.abs(np.exp(lb) - table.beta[ok]) / table.beta[ok]))
        m["coverage"] = float(np.mean(np.abs(lb - y) <= q * s))
        m["interval_ratio_median"] = float(np.median(np.exp(2 * q * s)))
    if alarm is not None and alarm.thresholds:
        flags = np.array(
            [
                alarm.evaluate({k: table.checks[k][i] for k in table.checks})["flag"]
                for i in range(len(table.label))
            ]
        )
        m["alarm_rate"] = float(flags.mean())
        wrong = table.pred != table.label
        m["alarm_rate_wrong"] = float(flags[wrong].mean()) if wrong.any() else np.nan
        m["alarm_rate_right"] = float(flags[~wrong].mean()) if (~wrong).any() else np.nan
    return m


def calibrate_recording_level(
    traj: np.ndarray,
    label: np.ndarray,
    beta: np.ndarray,
    split: Any,
    outputs: dict[str, np.ndarray],
    coverage: float,
    target: float,
    seed: int,
    info: dict[str, Any],
    checks: list[str] | None = None,
    classes: np.ndarray | None = None,
) -> tuple[AlarmReference, float, dict[str, float]]:
    """The alarm, the recording-level conformal quantile and the test trajectories' metrics.

    `outputs` holds the model's window outputs for every window of the dataset
    (NaN-free where the split needs them); `split` is the trajectory-wise split;
    ``classes`` is the class index of each probability column (:func:`trajectory_table`).
    """
    train_emb = None
    if "embedding" in outputs:
        tr = np.flatnonzero(split.train)
        rng = np.random.default_rng(seed)
        pick = np.sort(rng.choice(tr, size=min(MAX_REFERENCE_WINDOWS, tr.size), replace=False))
        train_emb = outputs["embedding"][pick]
    cal = split.cal

    def part(mask: np.ndarray) -> dict[str, np.ndarray]:
        return {k: v[mask] for k, v in outputs.items()}

    alarm, _ = fit_alarm(train_emb, traj[cal], label[cal], beta[cal], part(cal), target, seed,
                         info, checks, classes)  # fmt: skip
    q = recording_quantile(
        trajectory_table(traj[cal], label[cal], beta[cal], part(cal), alarm, classes=classes),
        coverage,
    )
    te = split.test
    table = trajectory_table(traj[te], label[te], beta[te], part(te), alarm, classes=classes)
    return alarm, q, trajectory_metrics(table, q, alarm)
