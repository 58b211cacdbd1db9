"""The gradient-boosting family: the inclination features of every window in."""

from __future__ import annotations

import numpy as np

from serving.families.base import ModelFamily
from stiffnet.features import FEATURE_NAMES


class GBMFamily(ModelFamily):
    """HistGradientBoosting classifier and regressor on inclination features.

    The model reads the features of every window (so the geometric cross-check
    sees them all at no extra cost). A model trained without the natural
    frequency (metadata ``requires_natural_frequency: false``) gets its
    ``period_natural`` feature masked as in training.
    """

    kind = "gbm"
    model_kind = "stiffnet.gbm"
    input_name = "features"

    def feature_windows(self, n_windows: int, geometric_windows: int) -> np.ndarray:
        return np.arange(n_windows)

    def model_input(
        self, windows: np.ndarray, fs_hz: float, natural_frequency_hz: float, features: np.ndarray
    ) -> np.ndarray:
        X = features
        if not self.metadata.get("requires_natural_frequency", True):
            X = features.copy()
            X[:, FEATURE_NAMES.index("period_natural")] = -1.0
        return X.astype(np.float32)
