"""Hand-crafted features of one acceleration window for the learned models (numpy/scipy only).

Never import torch, sklearn or mlflow here: the light ONNX predictor imports
this package to turn a recording into the feature vector its model expects.
"""

from stiffnet.features.inclination_features import (
    FEATURE_NAMES,
    FEATURE_VERSION,
    FILL_VALUES,
    feature_matrix,
    features_and_estimate,
    inclination_features,
)

__all__ = [
    "FEATURE_NAMES",
    "FEATURE_VERSION",
    "FILL_VALUES",
    "feature_matrix",
    "features_and_estimate",
    "inclination_features",
]
