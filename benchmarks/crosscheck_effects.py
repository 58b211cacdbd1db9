"""A contact law the library lacks, loaded as ``crosscheck_effects:PowerLawContact``.

bench_crosscheck.py and tests/test_restoring_force.py use it to check the
restoring-force estimate on a restraint stiffer than linear with a non-Hertz
exponent (a rough, conforming contact: force ~ penetration**1.3).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from stiffnet.effects.base import DynamicsEffect, EffectParams, ParamArrays, ParamValue, param


class PowerLawContact(DynamicsEffect):
    """``F_c = beta d_r (d / d_r)**n``: secant stiffness ``beta`` at the penetration ``d_r``."""

    name = "power_law_contact"

    class Params(EffectParams):
        exponent: ParamValue = param(1.3, 0.5, 3.0, "contact exponent n")
        reference_penetration: ParamValue = param(
            0.3, 1e-3, 10.0, "penetration where the secant stiffness is beta", "model length"
        )

    def elastic_contact(self, delta: np.ndarray, p: ParamArrays, batch: Any) -> np.ndarray:
        dr = p["reference_penetration"]
        return batch.beta * dr * (np.maximum(delta, 0.0) / dr) ** p["exponent"]
