"""The gradient-boosting family: HistGradientBoosting classifier and log-beta regressor
on the inclination features of each window (the fast baseline; ``stiffnet train``'s default).

* :mod:`.config`: its config section (``gbm:``);
* :mod:`.model`: the two scikit-learn models and their fit;
* :mod:`.export`: one ONNX graph (skl2onnx) with the feature contract in its metadata;
* :mod:`.train`: inputs and fit for the shared tail (:mod:`training.finish`);
* serving half: :mod:`serving.families.gbm`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from serving.families.gbm import GBMFamily
from training.families.base import TrainedModel, TrainingFamily
from training.families.gbm.config import GBMConfig


class GBMTraining(TrainingFamily):
    """Training half of the gradient-boosting family (see the package notes)."""

    name = "gbm"
    config = GBMConfig
    serving = GBMFamily
    defaults = ("train",)

    def inputs(self, ds: Any, config: Any) -> np.ndarray:
        from training.families.gbm.train import gbm_inputs

        return gbm_inputs(ds, config.use_natural_frequency, config.n_jobs)

    def fit(
        self, X: np.ndarray, ds: Any, split: Any, config: Any, say: Callable[[str], None]
    ) -> TrainedModel:
        from training.families.gbm.train import fit_gbm_family

        return fit_gbm_family(X, ds, split, config, say)

    def inputs_from_metadata(self, ds: Any, metadata: dict[str, Any]) -> np.ndarray:
        from training.families.gbm.train import gbm_inputs

        use_fn = bool(metadata.get("requires_natural_frequency", True))
        return gbm_inputs(ds, use_fn).astype(np.float32)
