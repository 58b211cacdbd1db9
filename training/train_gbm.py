"""Train the gradient-boosting models end to end: inclination features, fit, shared tail.

:func:`train_gbm` loads a dataset, extracts the inclination features of every
window (:class:`training.transformers.InclinationFeatures`), splits by
trajectory, fits the classifier and the log-beta regressor
(:func:`training.gbm.fit_gbm`) and hands them to the tail both families share
(:func:`training.finish.finish_training`: interval and alarm calibration,
metrics against the geometric method, ONNX export with card, MLflow).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import sklearn

from stiffnet.config.train import TrainConfig
from stiffnet.features import FEATURE_NAMES, FEATURE_VERSION
from training.export_onnx import export_onnx, parity
from training.finish import TrainedModel, finish_training
from training.gbm import fit_gbm
from training.split import split_windows
from training.training_data import load_training_data
from training.transformers import InclinationFeatures, window_records


def train_gbm(
    data_dir: str | Path,
    config: TrainConfig,
    out_dir: str | Path,
    tracking_uri: str | None = None,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Train, evaluate, export (``gbm.onnx``) and track the GBM models on one dataset.

    Same contract as :func:`training.train.train` (which dispatches here for
    ``model: gbm``); the summary's ``timing`` has ``features_s`` and ``fit_s``.
    """
    say = progress or (lambda _msg: None)
    t0 = time.perf_counter()
    data_dir, out_dir = Path(data_dir), Path(out_dir)
    ds, names, card_sha = load_training_data(data_dir, say)

    t = time.perf_counter()
    feats = InclinationFeatures(config.use_natural_frequency, n_jobs=config.n_jobs)
    X = feats.fit_transform(window_records(ds))
    t_feat = time.perf_counter() - t
    say(f"features: {X.shape[1]} per window, {1e3 * t_feat / max(1, len(ds)):.1f} ms/window")

    label, beta = ds.column("label"), ds.column("beta")
    sp = split_windows(ds, data_dir, config, config.gbm.validation_fraction, say)

    t = time.perf_counter()
    clf, reg = fit_gbm(X, label, beta, sp, config.gbm, config.seed)
    t_fit = time.perf_counter() - t
    say(f"fitted: classifier {clf.n_iter_} iterations, regressor {reg.n_iter_} ({t_fit:.1f} s)")

    model = TrainedModel(
        name="gbm",
        inputs=X,
        outputs={"probabilities": clf.predict_proba(X), "log_beta": reg.predict(X)},
        classes=clf.classes_,
        export=lambda path, metadata, card: export_onnx(
            clf, reg, FEATURE_NAMES, names, path, metadata=metadata, card=card
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
            **{f"gbm.{k}": v for k, v in config.gbm.model_dump().items()},
        },
        timing={"features_s": t_feat, "fit_s": t_fit},
    )
    return finish_training(
        model, ds=ds, data_dir=data_dir, out_dir=out_dir, card_sha=card_sha, split=sp,
        config=config, tracking_uri=tracking_uri, say=say, started=t0,
    )  # fmt: skip
