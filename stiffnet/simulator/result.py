"""What an engine returns: the sampled motion of a batch, before the measurement chain."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class EngineResult:
    """Sampled trajectories of ``B`` rows, ``(B, N)`` arrays unless noted.

    Every engine (the compiled closed form, the numerical RK4, the closed-form
    oracle) returns this; :class:`~stiffnet.simulator.simulator.Simulator` applies
    the measurement chain to ``accel``.

    Attributes
    ----------
    x, v : relative displacement and velocity of the mass (model units).
    accel : absolute acceleration of the mass: the spring, damper and contact
        forces (plus any extra force of an effect).
    contact_force : force of the restraint, 0 in free flight.
    impacts : int8, contact entries during the sampling interval that ends at
        each sample.
    t0 : (B,), model time of each row's first sample.
    """

    x: np.ndarray
    v: np.ndarray
    accel: np.ndarray
    contact_force: np.ndarray
    impacts: np.ndarray
    t0: np.ndarray
