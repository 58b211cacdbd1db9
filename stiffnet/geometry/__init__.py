"""The paper's geometric stiffness method (section 5), numpy/scipy only.

One topic per module, in the style of :mod:`stiffnet.nlts`: functions that
estimate whole arrays (tangents, histograms, per-orbit angles) and separate
rules that pick a number.

=================  ==============================================================
``tangent``        tangent vectors of the embedded trajectory and their magnitudes (eqs 4-6)
``separation``     contact / free-flight split of the tangent magnitudes (Fig. 8)
``inclination``    inclinations before and after impact in the x-z projection
                   (gradient approach, eqs 7-10; polynomial fit, Table 1)
``calibration``    inclinations -> beta and stiffness class, fitted on simulations (Fig. 11)
``orbit``          which orbit the record is on (n impacts every m forcing periods)
``estimate``       :func:`geometric_estimate`, the whole chain on one record
``paper``          the paper's parameter set, Table 1, simulation on the period-1
                   branch (imports the simulator; not imported here)
=================  ==============================================================

Never import torch, sklearn, mlflow here, nor matplotlib at module level: the
ONNX predictor imports this package.
"""

from stiffnet.geometry.calibration import (
    DEFAULT_CALIBRATION_PATH,
    DEFAULT_CLASSES,
    NO_CONTACT,
    GeometricCalibration,
    beta_class,
    calibration_errors,
    fit_calibration,
    load_calibration,
    log_gradient,
    save_calibration,
)
from stiffnet.geometry.estimate import (
    GeometricResult,
    dominant_period,
    geometric_estimate,
    smoothing_window,
)
from stiffnet.geometry.inclination import (
    OrbitInclinations,
    curve_inclination,
    gradient_inclinations,
    impact_regions,
    polynomial_inclinations,
    tangent_inclinations,
    xz_projection,
)
from stiffnet.geometry.separation import (
    ContactSeparation,
    log_magnitude_histogram,
    otsu_curve,
    otsu_threshold,
    separate_contact,
)
from stiffnet.geometry.tangent import tangent_lag, tangent_magnitudes, tangent_vectors

__all__ = [
    "DEFAULT_CALIBRATION_PATH",
    "DEFAULT_CLASSES",
    "NO_CONTACT",
    "ContactSeparation",
    "GeometricCalibration",
    "GeometricResult",
    "OrbitInclinations",
    "beta_class",
    "calibration_errors",
    "curve_inclination",
    "dominant_period",
    "fit_calibration",
    "geometric_estimate",
    "gradient_inclinations",
    "impact_regions",
    "load_calibration",
    "log_gradient",
    "log_magnitude_histogram",
    "otsu_curve",
    "otsu_threshold",
    "polynomial_inclinations",
    "save_calibration",
    "separate_contact",
    "smoothing_window",
    "tangent_inclinations",
    "tangent_lag",
    "tangent_magnitudes",
    "tangent_vectors",
    "xz_projection",
]
