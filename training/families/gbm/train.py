"""The gradient-boosting family's training steps: inclination features in, two HGB models out.

:func:`gbm_inputs` extracts the inclination features of every window
(:class:`training.transformers.InclinationFeatures`); :func:`fit_gbm_family` fits
the classifier and the log-beta regressor (:func:`training.families.gbm.model.fit_gbm`)
and hands them to the tail every family shares (:func:`training.finish.finish_training`:
interval and alarm calibration, metrics against the geometric method, ONNX export
with card, MLflow) as a :class:`~training.families.base.TrainedModel`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import sklearn

from stiffnet.config.window import WINDOW_PERIODS
from stiffnet.features import FEATURE_NAMES, FEATURE_VERSION
from training.config import TrainConfig
from training.families.base import TrainedModel
from training.families.gbm.export import export_onnx, parity
from training.families.gbm.model import fit_gbm
from training.split import Split
from training.transformers import InclinationFeatures, window_records


def gbm_inputs(ds: Any, use_natural_frequency: bool, n_jobs: int = 1) -> np.ndarray:
    """The inclination features of every window of `ds` (float64, one row per window)."""
    feats = InclinationFeatures(use_natural_frequency, n_jobs=n_jobs)
    return feats.fit_transform(window_records(ds))


def window_periods(ds: Any) -> float:
    """Natural periods per window of the training data (the predictor cuts recordings alike)."""
    windows = (ds.card.get("config") or {}).get("windows") or {}
    return float(windows.get("duration_periods") or WINDOW_PERIODS)


def feature_contract(periods: float, use_natural_frequency: bool) -> dict[str, Any]:
    """How a recording becomes the model's input, for its ONNX metadata.

    With it and the ``feature_names``, a user feeds the model from plain onnxruntime
    (the features themselves are :func:`stiffnet.features.inclination_features` of
    ``feature_version``).
    """
    return {
        "feature_version": FEATURE_VERSION,
        "cut": {
            "window_samples": "max(8, round(window_periods * fs / f_n)) at the recording's rate",
            "hop_samples": "window_samples (non-overlapping, from sample 0)",
            "window_periods": periods,
        },
        "features": "stiffnet.features.inclination_features(window, fs_hz, f_n) of each "
        "window (gain- and polarity-invariant), float32, one row per window, columns in "
        "the order of feature_names",
        "natural_frequency": "f_n enters only period_natural"
        if use_natural_frequency
        else "period_natural is set to -1 (trained without f_n)",
        "aggregate": "class: arg-max of the mean probabilities over windows; beta: exp of the "
        "mean log_beta over the windows whose own class has contact; interval: exp(mean +- "
        "conformal_quantile_recording * scale), scale = sqrt(1 + var(log_beta))",
    }


def fit_gbm_family(
    X: np.ndarray, ds: Any, split: Split, config: TrainConfig, say: Callable[[str], None]
) -> TrainedModel:
    """Fit the classifier and the regressor on the ``train`` rows; the model and its hooks."""
    label, beta = ds.column("label"), ds.column("beta")
    clf, reg = fit_gbm(X, label, beta, split, config.section, config.seed)
    say(f"fitted: classifier {clf.n_iter_} iterations, regressor {reg.n_iter_}")
    return TrainedModel(
        name=str(config.model),
        inputs=X,
        outputs={"probabilities": clf.predict_proba(X), "log_beta": reg.predict(X)},
        classes=clf.classes_,
        export=lambda path, metadata, card: export_onnx(
            clf, reg, FEATURE_NAMES, ds.class_names, path, metadata=metadata, card=card
        ),
        parity=lambda path, rows: parity(path, clf, reg, rows),
        metadata={
            "feature_version": FEATURE_VERSION,
            "requires_natural_frequency": config.use_natural_frequency,
            "window_periods": window_periods(ds),
            "hop_periods": window_periods(ds),
            "feature_contract": feature_contract(window_periods(ds), config.use_natural_frequency),
        },
        versions={"sklearn_version": sklearn.__version__},
        card={"n_iter": {"classifier": int(clf.n_iter_), "regressor": int(reg.n_iter_)}},
        params={
            "use_natural_frequency": config.use_natural_frequency,
            **{f"{config.model}.{k}": v for k, v in config.section.model_dump().items()},
        },
    )
