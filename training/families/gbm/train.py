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
        },
        versions={"sklearn_version": sklearn.__version__},
        card={"n_iter": {"classifier": int(clf.n_iter_), "regressor": int(reg.n_iter_)}},
        params={
            "use_natural_frequency": config.use_natural_frequency,
            **{f"{config.model}.{k}": v for k, v in config.section.model_dump().items()},
        },
    )
