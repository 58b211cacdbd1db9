"""Gradient-boosting models on inclination features.

:func:`fit_gbm` fits a :class:`~sklearn.ensemble.HistGradientBoostingClassifier`
(no-contact plus the beta classes) and a
:class:`~sklearn.ensemble.HistGradientBoostingRegressor` on ``log(beta)``
(windows whose true label is a contact class), early-stopped on the validation
trajectories (:mod:`training.split`). End-to-end training: :mod:`training.families.gbm.train`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from sklearn.ensemble import HistGradientBoostingClassifier, HistGradientBoostingRegressor

from training.families.gbm.config import GBMConfig
from training.metrics import NO_CONTACT_LABEL
from training.split import Split


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
