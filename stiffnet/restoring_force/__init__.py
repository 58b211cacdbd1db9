"""The restoring-force (force-state mapping) estimate of beta, numpy/scipy only.

Masri & Caughey's restoring-force method (Worden & Tomlinson, *Nonlinearity in
Structural Dynamics*): the accelerometer on the mass reads the total restoring
force per unit mass, so with the relative displacement and velocity
reconstructed, the force-displacement map shows the contact law directly and
beta is the ratio of its contact slope to its free-flight slope. An explainable
cross-check beside the paper's geometric method (:mod:`stiffnet.geometry`).

=================  ==============================================================
``reconstruct``    forcing frequency, whole-period segment, frequency-domain
                   integration to relative velocity and displacement
``free_flight``    free-flight law ``-y = c v + k x`` with the table's motion at the
                   forcing harmonics; contact split; per-flight impulse corrections
``contact_law``    Kelvin-Voigt power law with release at zero force:
                   onset, stiffness, damping, exponent
``staged_law``     a model's learned two-stage law on the map (ratio held, knee free):
                   beta as its first-stage slope (one slope where no knee shows)
``chain``          the sensor chain (mount resonance, low-pass, high-pass) fitted
                   jointly with the contact pulse, or a data sheet; its inverse
``estimate``       :func:`restoring_force_estimate`: the chain, bootstrap interval
                   over impacts, goodness of fit, refusal reasons
=================  ==============================================================

Never import torch, sklearn, mlflow here, nor matplotlib: the predictor imports it.
"""

from stiffnet.restoring_force.chain import SensorChain, identify_sensor_chain
from stiffnet.restoring_force.contact_law import (
    ContactLaw,
    contact_force,
    exponent_matters,
    fit_contact_law,
    linear_contact_start,
)
from stiffnet.restoring_force.estimate import (
    RestoringForceResult,
    bootstrap_beta,
    impact_regions,
    restoring_force_estimate,
)
from stiffnet.restoring_force.free_flight import FreeFlightFit, fit_free_flight, table_motion
from stiffnet.restoring_force.reconstruct import (
    forcing_frequency,
    integrate_spectral,
    periodic_length,
)
from stiffnet.restoring_force.staged_law import StagedLaw, fit_staged_law

__all__ = [
    "ContactLaw",
    "FreeFlightFit",
    "RestoringForceResult",
    "SensorChain",
    "StagedLaw",
    "bootstrap_beta",
    "contact_force",
    "exponent_matters",
    "fit_contact_law",
    "fit_free_flight",
    "fit_staged_law",
    "forcing_frequency",
    "identify_sensor_chain",
    "impact_regions",
    "integrate_spectral",
    "linear_contact_start",
    "periodic_length",
    "restoring_force_estimate",
    "table_motion",
]
