"""The CNN family: canonical delay-embedded windows in, exactly as at training time."""

from __future__ import annotations

import numpy as np

from serving.families.base import ModelFamily, spread_windows
from stiffnet.features.windows import window_tensor


class CNNFamily(ModelFamily):
    """1-D CNN on canonical windows (:func:`stiffnet.features.windows.window_tensor`).

    The canonical rate, window length and channel delays come from the model's
    metadata; the geometric cross-check reads a few windows spread over the
    recording (the predictor's ``geometric_windows``).
    """

    kind = "cnn"
    model_kind = "stiffnet.cnn"
    input_name = "windows"
    required_metadata = ("canonical_rate", "window_periods", "delays")
    default = True  # models/cnn.onnx is the predictor's model unless another is named

    def feature_windows(self, n_windows: int, geometric_windows: int) -> np.ndarray:
        return spread_windows(n_windows, geometric_windows)

    def model_input(
        self, windows: np.ndarray, fs_hz: float, natural_frequency_hz: float, features: np.ndarray
    ) -> np.ndarray:
        m = self.metadata
        return window_tensor(
            windows,
            fs_hz,
            natural_frequency_hz,
            int(m["canonical_rate"]),
            int(m["window_periods"]),
            m["delays"],
        )
