"""The 1-D CNN family: a small convolutional network on canonical delay-embedded windows
(class and log-beta heads, an error-scale head and an embedding for the alarm; the
shipped model and the measurement loop's default).

* :mod:`.config`: its config section (``cnn:``);
* :mod:`.network`: the network, its fit (early stopping) and prediction (torch);
* :mod:`.export`: the ONNX export (weights inside, the window contract in the metadata);
* :mod:`.train`: inputs and fit for the shared tail (:mod:`training.finish`);
* serving half: :mod:`serving.families.cnn`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from serving.families.cnn import CNNFamily
from training.families.base import TrainedModel, TrainingFamily
from training.families.cnn.config import CNNConfig


class CNNTraining(TrainingFamily):
    """Training half of the CNN family (see the package notes)."""

    name = "cnn"
    config = CNNConfig
    serving = CNNFamily
    defaults = ("loop",)
    # the loop's datasets are 12 times smaller than the shipped model's (40 epochs):
    # fewer epochs, and a wall-clock guard on the fit
    loop_settings = {"max_epochs": 15, "patience": 5, "max_train_seconds": 480}

    def inputs(self, ds: Any, config: Any) -> np.ndarray:
        from training.families.cnn.train import cnn_inputs, config_delays

        cc = config.section
        return cnn_inputs(ds, cc.rate, cc.periods, config_delays(config))

    def fit(
        self, X: np.ndarray, ds: Any, split: Any, config: Any, say: Callable[[str], None]
    ) -> TrainedModel:
        from training.families.cnn.train import fit_cnn_family

        return fit_cnn_family(X, ds, split, config, say)

    def inputs_from_metadata(self, ds: Any, metadata: dict[str, Any]) -> np.ndarray:
        from training.families.cnn.train import cnn_inputs

        rate, periods = int(metadata["canonical_rate"]), int(metadata["window_periods"])
        return cnn_inputs(ds, rate, periods, list(metadata["delays"]))
