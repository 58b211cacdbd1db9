"""The toy ridge family's serving half: the inclination features of every window in."""

from __future__ import annotations

import numpy as np

from serving.families.base import ModelFamily


class RidgeServing(ModelFamily):
    """Linear models on the inclination features (numpy only, like every serving half)."""

    kind = "ridge"
    model_kind = "test.ridge"
    input_name = "features"
    required_metadata = ("feature_names",)

    def feature_windows(self, n_windows: int, geometric_windows: int) -> np.ndarray:
        return np.arange(n_windows)

    def model_input(
        self, windows: np.ndarray, fs_hz: float, natural_frequency_hz: float, features: np.ndarray
    ) -> np.ndarray:
        return np.asarray(features, dtype=np.float32)
