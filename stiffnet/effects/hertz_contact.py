"""Hertzian (sphere-on-flat) contact law in place of the linear restraint spring."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from stiffnet.effects.base import DynamicsEffect, EffectParams, ParamArrays, ParamValue, param
from stiffnet.effects.fit_space import FitParam, FitSpace


class HertzContact(DynamicsEffect):
    r"""Hertz contact: the restraint force grows as the penetration to the power 3/2.

    The linear restraint ``beta delta`` of eq. (12) is replaced by the elastic
    force of a sphere pressed on a flat (the rig's rounded bolt head on the
    beam)::

        F_c = k_h delta^(3/2),   k_h = beta / sqrt(delta_ref),   delta = x - e > 0

    ``delta_ref`` (``reference_penetration``) keeps ``beta`` meaningful: the
    secant stiffness ``F_c / delta = beta sqrt(delta / delta_ref)`` equals
    ``beta`` at ``delta = delta_ref``, is softer below it and stiffer above.
    Hertz theory gives ``k_h = (4/3) E* sqrt(R)``; fixing ``k_h`` through
    ``beta`` and ``delta_ref`` instead keeps the dataset's stiffness label.
    The default ``delta_ref = 0.5`` model length units is the order of the
    peak penetrations of the paper's parameter set (a = 1.9, w = 1.05,
    e = 2.8: about 0.4-2 for beta = 100-5), so beta keeps roughly its meaning
    at the penetrations the model actually reaches. Contact damping
    (``contact_damping`` of another effect) adds to it as usual.

    Signature on the acceleration: the force starts with zero slope
    (``dF_c/dt ~ delta^(1/2) -> 0``) where the linear law has a kink, so the
    impact spike has a smooth, rounded onset (the force grows as ``tau^1.5``
    after first touch, not ``tau``); below ``delta_ref`` the contact is
    softer, hence longer.

    The law is not twice differentiable at ``delta = 0``; the event-located RK4
    integrator therefore converges at about order 2.5 (not 4) across contact
    onset and release, with a very small constant.
    """

    name = "hertz_contact"
    #: Training-world prior (docs/priors.md): rounded contacts on some rigs.
    prior: ClassVar[dict | None] = {
        "probability": 0.12,
        "params": {"reference_penetration": [0.1, 2.0]},
    }

    class Params(EffectParams):
        reference_penetration: ParamValue = param(
            0.5,
            1e-3,
            10.0,
            "penetration at which the Hertz secant stiffness equals beta",
            "model length",
        )

    #: The penetration scale of the law (the elastic law tends to the linear one above it).
    fit_space = FitSpace((FitParam("reference_penetration", 0.01, 10.0, log=True),))

    def elastic_contact(self, delta: np.ndarray, p: ParamArrays, batch: Any) -> np.ndarray:
        """``beta / sqrt(delta_ref) * delta**1.5`` for penetrations ``delta >= 0``.

        Parameters
        ----------
        delta : numpy.ndarray
            Penetration, (B,), non-negative.
        p : dict of numpy.ndarray
            Per-row ``reference_penetration``, (B,).
        batch : OscillatorBatch
            Supplies ``beta``, (B,).

        Returns
        -------
        numpy.ndarray
            Elastic contact force, (B,).
        """
        k_h = batch.beta / np.sqrt(p["reference_penetration"])
        return k_h * delta * np.sqrt(delta)
