"""Nonlinear time-series toolkit (numpy/scipy only), after the paper's sections 3-4.

One topic per module, in the style of nolitsa / DelayEmbeddings.jl: functions
that estimate a curve (AMI, FNN fractions, Cao's E1/E2, cross-prediction
errors, vector field) and separate *rule* functions that pick a number from it.

========================  ==========================================================
``preprocess``            Savitzky-Golay smoothing, impact indicators and detection
``embedding``             delay vectors (eq. 1)
``delay``                 auto-mutual information (eq. 2), autocorrelation, delay rules
``dimension``             false nearest neighbours, Cao's E1/E2 (eq. 3), dimension rules
``stationarity``          cross-prediction errors between segments (section 4.2.1)
``determinism``           Kaplan-Glass vector-field test (section 4.2.2)
========================  ==========================================================

Never import torch, sklearn, mlflow or matplotlib here: the ONNX predictor
imports this package.
"""

from stiffnet.nlts._validate import as_signal
from stiffnet.nlts.delay import (
    Estimate,
    autocorrelation,
    autocorrelation_decay_time,
    estimate_delay,
    first_minimum,
    first_prominent_minimum,
    mutual_information,
)
from stiffnet.nlts.determinism import (
    VectorField,
    approximate_vector_field,
    determinism_factor,
    kaplan_glass,
)
from stiffnet.nlts.dimension import (
    cao_curves,
    cao_dimension,
    estimate_dimension,
    false_nearest_neighbours,
    fnn_dimension,
)
from stiffnet.nlts.embedding import delay_embed
from stiffnet.nlts.preprocess import (
    detect_impacts,
    impact_indicator_derivative,
    impact_indicator_rms,
    robust_threshold,
    savgol_smooth,
)
from stiffnet.nlts.stationarity import cross_prediction_errors, is_stationary

__all__ = [
    "Estimate",
    "VectorField",
    "approximate_vector_field",
    "as_signal",
    "autocorrelation",
    "autocorrelation_decay_time",
    "cao_curves",
    "cao_dimension",
    "cross_prediction_errors",
    "delay_embed",
    "detect_impacts",
    "determinism_factor",
    "estimate_delay",
    "estimate_dimension",
    "false_nearest_neighbours",
    "first_minimum",
    "first_prominent_minimum",
    "fnn_dimension",
    "impact_indicator_derivative",
    "impact_indicator_rms",
    "is_stationary",
    "kaplan_glass",
    "mutual_information",
    "robust_threshold",
    "savgol_smooth",
]
