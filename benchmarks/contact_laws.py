"""Contact laws the effect library lacks, written as user effects (``module:Class``).

The robustness benchmark (``bench_robustness.py``) hides them in test rigs to see
what the models and the alarm do on physics they were never trained on. They are
also the worked example of a user effect: a ``DynamicsEffect`` subclass that
overrides ``elastic_contact`` (the simulator then integrates numerically with
event location). Load one as ``benchmarks.contact_laws:PowerLawContact`` with
the repository root on ``sys.path``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from stiffnet.effects.base import DynamicsEffect, EffectParams, ParamArrays, ParamValue, param


class PowerLawContact(DynamicsEffect):
    r"""Power-law contact ``F = beta d_ref (delta / d_ref)^n``.

    ``n = 1`` is the paper's linear restraint, ``n = 1.5`` Hertz's sphere on a
    flat (the library's ``hertz_contact``); rough or conforming contacts and
    layered rock show other exponents. The secant stiffness equals beta at
    ``delta = d_ref``, so beta keeps its meaning at the penetrations reached.
    """

    name = "power_law_contact"

    class Params(EffectParams):
        exponent: ParamValue = param(2.0, 1.0, 3.0, "exponent n of the contact law", "")
        reference_penetration: ParamValue = param(
            0.5, 1e-3, 10.0, "penetration at which the secant stiffness is beta", "model length"
        )

    def elastic_contact(self, delta: np.ndarray, p: ParamArrays, batch: Any) -> np.ndarray:
        d0 = p["reference_penetration"]
        return batch.beta * d0 * (delta / d0) ** p["exponent"]


class BilinearContact(DynamicsEffect):
    r"""A contact that stiffens by ``ratio`` past the penetration ``knee``.

    ``F = beta delta`` for ``delta <= knee``, ``beta (knee + ratio (delta - knee))``
    beyond: a thin soft layer (paint, a rubber pad, weathered rock) over a
    stiffer body.
    """

    name = "bilinear_contact"

    class Params(EffectParams):
        knee: ParamValue = param(0.2, 1e-3, 10.0, "penetration where the stiffness jumps", "")
        ratio: ParamValue = param(3.0, 0.1, 20.0, "stiffness beyond the knee / beta", "")

    def elastic_contact(self, delta: np.ndarray, p: ParamArrays, batch: Any) -> np.ndarray:
        knee = p["knee"]
        return batch.beta * np.where(delta <= knee, delta, knee + p["ratio"] * (delta - knee))


class HuntCrossleyContact(DynamicsEffect):
    r"""Hunt & Crossley (1975): a dissipation that scales with penetration.

    ``F = beta delta (1 + lam v)``: the damping force grows with the penetration (zero
    at first touch, so no force jump at onset), unlike the library's Kelvin-Voigt
    ``contact_damping`` (``c v``); wet or crushing rock, rubber pads.
    """

    name = "hunt_crossley_contact"

    class Params(EffectParams):
        lam: ParamValue = param(0.5, 0.0, 5.0, "dissipation per unit velocity", "model time/length")

    def elastic_contact(self, delta: np.ndarray, p: ParamArrays, batch: Any) -> np.ndarray:
        return np.asarray(batch.beta, float) * delta

    def contact_dissipation(
        self, delta: np.ndarray, rate: np.ndarray, p: ParamArrays, batch: Any
    ) -> np.ndarray:
        return p["lam"] * np.asarray(batch.beta, float) * delta * rate
