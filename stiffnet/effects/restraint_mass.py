"""A restraint (the beam) with its own mass, stiffness and damping."""

from __future__ import annotations

from typing import Any

import numpy as np

from stiffnet.effects.base import DynamicsEffect, EffectParams, ParamArrays, ParamValue, param
from stiffnet.effects.fit_space import FitParam, FitSpace


class RestraintMass(DynamicsEffect):
    r"""The restraint as a mass on a spring: it is pushed by the impacts and rings.

    Eq. (12) treats the beam as a massless spring. Here its contact face moves
    with a displacement ``y`` (positive away from the mass, model length
    units), a single-mode model of the beam::

        mu y'' = F_c - kappa y - 2 zeta sqrt(kappa mu) y'
        F_c    = beta (x - e - y)   while x - e - y > 0 (and the force pushes)
        x''    = a w^2 sin(w t) - 2 xi x' - x - F_c

    with ``mu = m_r / m`` (``mass_ratio``), ``kappa = k_r / k``
    (``stiffness_ratio``, the beam's support stiffness relative to the primary
    spring) and ``zeta`` (``damping_ratio``, the beam's own damping ratio), in
    the model's units (forces per primary-spring stiffness, time in
    ``1 / omega_n``). The contact itself keeps stiffness ``beta`` (with an
    ``elastic_contact`` or ``contact_damping`` effect, those laws), in series
    with the beam: the static stiffness is ``beta kappa / (beta + kappa)``.
    The beam rings at ``sqrt(kappa / mu)`` times the mass's natural frequency
    when free and at ``sqrt((kappa + beta) / mu)`` while in contact.

    The default ``kappa = 100`` keeps the beam much stiffer than typical
    contacts (``beta`` 5-100), so ``beta`` stays the dominant, identifiable
    stiffness; ``mu = 0.1`` and ``zeta = 0.05`` stand for a light, lightly
    damped steel beam. The integrator resolves the ringing: it takes more
    substeps than asked where :meth:`fastest_rate` times the substep would
    exceed 1 (below ~0.3 the ringing is accurate to ~1e-4 of the spike).

    Signature on the acceleration: the light beam recoils at the first touch
    and comes back, so the contact pulse is ragged or multi-peaked (and may
    split into several contacts) instead of a single smooth half-sine, and the
    contact lasts a different time than against a massless restraint.
    """

    name = "restraint_mass"
    n_states = 2  # y, y'

    class Params(EffectParams):
        mass_ratio: ParamValue = param(
            0.1, 1e-3, 10.0, "mass of the restraint's moving part over the mass m", ""
        )
        stiffness_ratio: ParamValue = param(
            100.0, 0.1, 1e4, "support stiffness of the restraint over the primary spring", ""
        )
        damping_ratio: ParamValue = param(
            0.05, 0.0, 2.0, "damping ratio of the restraint on its support", ""
        )

    #: The restraint's mass and support stiffness; its own damping held at the default.
    fit_space = FitSpace(
        (
            FitParam("mass_ratio", 0.1, 3.0, log=True),
            FitParam("stiffness_ratio", 1.0, 100.0, log=True),
        ),
        fixed={"damping_ratio": 0.05},
        multimodal=("stiffness_ratio",),
    )

    def fastest_rate(self, p: ParamArrays, batch: Any) -> np.ndarray:
        """Upper bound of the coupled system's fastest rate, (B,), rad per model time.

        The largest eigenvalue of the mass-normalised stiffness is at most its
        trace ``(1 + beta) + (kappa + beta) / mu``; the beam's damping adds its rate.
        """
        mu, kappa = p["mass_ratio"], p["stiffness_ratio"]
        k = 1.0 + batch.beta + (kappa + batch.beta) / mu
        c = 2.0 * p["damping_ratio"] * np.sqrt(kappa / mu)
        return 0.5 * c + np.sqrt(0.25 * c * c + k)

    def initial_states(self, p: ParamArrays, batch: Any) -> np.ndarray:
        """The restraint starts at rest in its unloaded position, (B, 2) zeros."""
        return np.zeros((len(batch), 2))

    def restraint_position(self, s: np.ndarray, p: ParamArrays) -> np.ndarray:
        """Displacement ``y`` of the contact face, (B,)."""
        return s[:, 0]

    def restraint_rate(self, s: np.ndarray, p: ParamArrays) -> np.ndarray:
        """Velocity ``y'`` of the contact face, (B,): its own state."""
        return s[:, 1]

    def state_derivative(
        self, t: np.ndarray, s: np.ndarray, contact_force: np.ndarray, p: ParamArrays
    ) -> np.ndarray:
        """``(y', y'')`` of the restraint driven by the contact force, (B, 2).

        Parameters
        ----------
        t : numpy.ndarray
            Time, (B,) (unused: the restraint is autonomous).
        s : numpy.ndarray
            ``(y, y')``, (B, 2).
        contact_force : numpy.ndarray
            Force of the mass on the restraint (>= 0, pushes it away), (B,).
        p : dict of numpy.ndarray
            Per-row ``mass_ratio``, ``stiffness_ratio``, ``damping_ratio``.

        Returns
        -------
        numpy.ndarray
            Time derivative of ``s``, (B, 2).
        """
        mu, kappa = p["mass_ratio"], p["stiffness_ratio"]
        damping = 2.0 * p["damping_ratio"] * np.sqrt(kappa * mu)
        y, w = s[:, 0], s[:, 1]
        out = np.empty_like(s)
        out[:, 0] = w
        out[:, 1] = (contact_force - kappa * y - damping * w) / mu
        return out
