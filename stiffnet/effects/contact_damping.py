"""Kelvin-Voigt damping in the contact: energy lost at every impact."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from stiffnet.effects.base import DynamicsEffect, EffectParams, ParamArrays, ParamValue, param
from stiffnet.effects.fit_space import FitParam, FitSpace


class ContactDamping(DynamicsEffect):
    r"""Viscous (Kelvin-Voigt) damping in parallel with the restraint's spring.

    The contact force becomes

    .. math:: F_c = \max\bigl(0,\ \beta\,\delta + c_c\,\dot\delta\bigr),\quad
              c_c = 2\,\zeta_c\sqrt{\beta},\qquad \delta = x - e > 0

    with :math:`\zeta_c` the damping ratio of the restraint's own spring on the
    unit mass. The ``max`` is physical: the restraint pushes but never pulls, so
    contact ends when the force reaches zero, slightly before the penetration
    does. Real beams and rock dissipate energy at each impact (coefficient of
    restitution below one); the base model of eq. (12) is perfectly elastic.

    Signature on the acceleration: the spike is asymmetric (steeper rise, the
    force jumps to :math:`c_c\dot\delta` at onset) and lower for the same approach
    velocity; less energy is returned, so rebounds are slower.
    """

    name = "contact_damping"
    neutral = {"damping_ratio": 0.0}
    #: Training-world prior (docs/priors.md): restitution from 1 down to ~0.3.
    prior: ClassVar[dict | None] = {"probability": 0.85, "params": {"damping_ratio": [0.0, 0.5]}}

    class Params(EffectParams):
        damping_ratio: ParamValue = param(
            0.1, 0.0, 1.0, "damping ratio of the contact spring, c_c = 2 zeta_c sqrt(beta)"
        )

    #: The contact's damping ratio; 0.6 is a restitution coefficient of about 0.1.
    fit_space = FitSpace((FitParam("damping_ratio", 0.0, 0.6),))

    def contact_damping(self, p: ParamArrays, batch: Any) -> np.ndarray:
        return 2.0 * p["damping_ratio"] * np.sqrt(batch.beta)
