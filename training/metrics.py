"""Test metrics of a stiffness model (GBM, CNN and the geometric method alike).

:func:`evaluate` computes accuracy, per-class recall, macro-F1, beta MAPE and
interval coverage overall and per noise level; :func:`confusion` the confusion
matrix logged with the run.
"""

from __future__ import annotations

import numpy as np
from sklearn.metrics import confusion_matrix, f1_score, recall_score

#: Class index of the windows without contact (the dataset's label 0).
NO_CONTACT_LABEL = 0


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
