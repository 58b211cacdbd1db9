"""Gradient-boosting models on inclination features: trajectory-wise splits, training,
split-conformal beta intervals and metrics (GBM and the geometric method alike).

* :func:`trajectory_split` assigns whole trajectories to train / validation /
  calibration / test, so windows of one trajectory never straddle two parts.
* :func:`fit_gbm` fits a :class:`~sklearn.ensemble.HistGradientBoostingClassifier`
  (no-contact plus the beta classes) and a
  :class:`~sklearn.ensemble.HistGradientBoostingRegressor` on ``log(beta)``
  (windows whose true label is a contact class), early-stopped on the
  validation trajectories.
* :func:`conformal_quantile`: split-conformal half-width on ``log(beta)`` from
  the calibration trajectories; the interval is ``exp(pred -+ q)``.
* :func:`evaluate` computes accuracy, per-class recall, macro-F1 and beta
  MAPE overall and per noise level.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from sklearn.ensemble import HistGradientBoostingClassifier, HistGradientBoostingRegressor
from sklearn.metrics import confusion_matrix, f1_score, recall_score

from stiffnet.config.train import GBMConfig

NO_CONTACT_LABEL = 0


@dataclass(frozen=True)
class Split:
    """Boolean window masks of a trajectory-wise split."""

    train: np.ndarray
    val: np.ndarray
    cal: np.ndarray
    test: np.ndarray


def trajectory_split(
    trajectory: np.ndarray,
    test_fraction: float,
    calibration_fraction: float,
    validation_fraction: float,
    seed: int,
) -> Split:
    """Split windows by trajectory into train, validation, calibration and test.

    Parameters
    ----------
    trajectory : numpy.ndarray
        Trajectory id of each window.
    test_fraction, calibration_fraction : float
        Fractions of all trajectories for test and conformal calibration.
    validation_fraction : float
        Fraction of the remaining (training) trajectories kept for early stopping.
    seed : int
        Seed of the trajectory permutation.

    Returns
    -------
    Split
        Disjoint masks covering every window; each part gets at least one
        trajectory when there are at least four.
    """
    ids = np.unique(trajectory)
    perm = np.random.default_rng(seed).permutation(ids)
    n = ids.size
    n_test = max(1, int(round(test_fraction * n))) if n >= 4 else 0
    n_cal = max(1, int(round(calibration_fraction * n))) if n >= 4 else 0
    n_rest = n - n_test - n_cal
    n_val = max(1, int(round(validation_fraction * n_rest))) if n_rest >= 2 else 0
    parts = np.split(perm, np.cumsum([n_test, n_cal, n_val]))
    test, cal, val, train = (np.isin(trajectory, p) for p in parts)
    return Split(train=train, val=val, cal=cal, test=test)


def _hgb_params(cfg: GBMConfig, seed: int) -> dict[str, Any]:
    return {
        "learning_rate": cfg.learning_rate,
        "max_iter": cfg.max_iter,
        "max_leaf_nodes": cfg.max_leaf_nodes,
        "max_depth": cfg.max_depth,
        "min_samples_leaf": cfg.min_samples_leaf,
        "l2_regularization": cfg.l2_regularization,
        "max_bins": cfg.max_bins,
        "early_stopping": cfg.early_stopping,
        "n_iter_no_change": cfg.n_iter_no_change,
        "random_state": seed,
    }


def _fit(model: Any, X: np.ndarray, y: np.ndarray, Xv: np.ndarray, yv: np.ndarray) -> Any:
    """Fit, early-stopping on the given validation set (sklearn's own split if it is empty)."""
    if model.early_stopping and len(yv) > 0 and len(np.unique(yv)) > 0:
        if isinstance(model, HistGradientBoostingClassifier) and not set(yv) <= set(y):
            keep = np.isin(yv, y)  # classes unseen in training cannot be scored
            Xv, yv = Xv[keep], yv[keep]
        if len(yv) > 0:
            return model.fit(X, y, X_val=Xv, y_val=yv)
    return model.fit(X, y)


def fit_gbm(
    X: np.ndarray,
    label: np.ndarray,
    beta: np.ndarray,
    split: Split,
    cfg: GBMConfig,
    seed: int,
) -> tuple[HistGradientBoostingClassifier, HistGradientBoostingRegressor]:
    """Fit the classifier and the log-beta regressor on the training trajectories.

    Parameters
    ----------
    X : numpy.ndarray
        Features of all windows, shape (n, k).
    label : numpy.ndarray
        Class index (0 = no contact).
    beta : numpy.ndarray
        True stiffness ratio.
    split : Split
        Trajectory-wise split; ``train`` fits, ``val`` early-stops.
    cfg : GBMConfig
        Hyper-parameters.
    seed : int
        Random state of both models.

    Returns
    -------
    classifier, regressor
        Fitted models (the regressor sees contact windows only).
    """
    p = _hgb_params(cfg, seed)
    clf = HistGradientBoostingClassifier(class_weight=cfg.class_weight, **p)
    _fit(clf, X[split.train], label[split.train], X[split.val], label[split.val])
    tr = split.train & (label != NO_CONTACT_LABEL)
    va = split.val & (label != NO_CONTACT_LABEL)
    reg = HistGradientBoostingRegressor(**p)
    _fit(reg, X[tr], np.log(beta[tr]), X[va], np.log(beta[va]))
    return clf, reg


def conformal_quantile(residuals: np.ndarray, coverage: float) -> float:
    """Split-conformal half-width: the ``ceil((n + 1) coverage) / n`` empirical quantile.

    Parameters
    ----------
    residuals : numpy.ndarray
        Absolute residuals ``|log beta - prediction|`` on the calibration windows.
    coverage : float
        Target coverage in (0, 1).

    Returns
    -------
    float
        Half-width in log-beta units (``inf`` if there are too few residuals).
    """
    r = np.sort(np.abs(np.asarray(residuals, dtype=np.float64)))
    n = r.size
    k = math.ceil((n + 1) * coverage)
    return float(r[k - 1]) if 0 < k <= n else float("inf")


def noise_bin_names(edges: list[float]) -> list[str]:
    """Names of the noise bins: ``noise_<edge>`` for ``(prev, edge]`` and ``noise_gt<last>``."""
    return [f"noise_{e:g}" for e in edges] + [f"noise_gt{edges[-1]:g}"]


def noise_bins(noise: np.ndarray, edges: list[float]) -> np.ndarray:
    """Bin index of each noise level: 0 for ``noise <= edges[0]``, k for
    ``(edges[k-1], edges[k]]``, ``len(edges)`` above the last edge."""
    return np.searchsorted(np.asarray(edges, dtype=np.float64), noise, side="left")


def _metrics(
    y: np.ndarray,
    pred: np.ndarray,
    beta: np.ndarray,
    beta_hat: np.ndarray,
    class_names: list[str],
    lo: np.ndarray | None = None,
    hi: np.ndarray | None = None,
) -> dict[str, float]:
    labels = list(range(len(class_names)))
    out: dict[str, float] = {"n": float(y.size), "accuracy": float(np.mean(pred == y))}
    out["macro_f1"] = float(f1_score(y, pred, labels=labels, average="macro", zero_division=0))
    rec = recall_score(y, pred, labels=labels, average=None, zero_division=np.nan)
    for name, r in zip(class_names, rec, strict=True):
        if np.isfinite(r):
            out[f"recall/{name}"] = float(r)
    contact = y != NO_CONTACT_LABEL
    est = contact & np.isfinite(beta_hat)
    if contact.any():
        out["beta_estimated_fraction"] = float(est.sum() / contact.sum())
    if est.any():
        out["beta_mape"] = float(np.mean(np.abs(beta_hat[est] - beta[est]) / beta[est]))
        out["beta_median_ape"] = float(np.median(np.abs(beta_hat[est] - beta[est]) / beta[est]))
        if lo is not None and hi is not None:
            b = beta[contact]
            out["beta_coverage"] = float(np.mean((lo[contact] <= b) & (b <= hi[contact])))
    return out


def evaluate(
    y: np.ndarray,
    pred: np.ndarray,
    beta: np.ndarray,
    beta_hat: np.ndarray,
    noise: np.ndarray,
    class_names: list[str],
    noise_edges: list[float],
    lo: np.ndarray | None = None,
    hi: np.ndarray | None = None,
) -> dict[str, float]:
    """Classification and beta metrics overall and per noise level.

    Parameters
    ----------
    y, pred : numpy.ndarray
        True and predicted class indices.
    beta, beta_hat : numpy.ndarray
        True beta and its estimate (NaN where the method gives none; such
        contact windows are left out of the MAPE and counted by
        ``beta_estimated_fraction``).
    noise : numpy.ndarray
        Noise level of each window.
    class_names : list of str
        Names of the class indices.
    noise_edges : list of float
        Noise bin edges (:func:`noise_bins`).
    lo, hi : numpy.ndarray, optional
        Beta interval bounds, for ``beta_coverage``.

    Returns
    -------
    dict
        Flat ``{"accuracy": ..., "recall/soft": ..., "noise_0.05/accuracy": ...}``;
        empty noise bins are left out.
    """
    out = _metrics(y, pred, beta, beta_hat, class_names, lo, hi)
    idx = noise_bins(noise, noise_edges)
    for k, name in enumerate(noise_bin_names(noise_edges)):
        m = idx == k
        if m.any():
            sub = _metrics(
                y[m],
                pred[m],
                beta[m],
                beta_hat[m],
                class_names,
                None if lo is None else lo[m],
                None if hi is None else hi[m],
            )
            out.update({f"{name}/{key}": v for key, v in sub.items()})
    return out


def confusion(y: np.ndarray, pred: np.ndarray, n_classes: int) -> np.ndarray:
    """Confusion matrix (rows: true class, columns: predicted) over all class indices."""
    return confusion_matrix(y, pred, labels=list(range(n_classes)))
